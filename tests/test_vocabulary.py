"""One vocabulary (issue 51): every public function's keywords come from one list
(accelcal.vocabulary.KEYWORDS), each the name of the command-line option that takes the same
value; help() shows them with their units; docs/api.md is what tools/api_doc.py generates now."""
import argparse
import inspect
import pydoc
import runpy

import accelcal
from accelcal.cli import build_parser
from accelcal.vocabulary import KEYWORDS
from conftest import ROOT

# each public function and the command that does the same
COMMANDS = {"calibrate": ("calibrate",), "calibrate_file": ("calibrate",),
            "diagnose": ("diagnose",), "compare": ("compare",), "apply": ("apply",),
            "simulate_wrist": ("simulate", "wrist"), "Job.of": ("calibrate",)}
IN_MEMORY_ONLY = {"rate", "temp", "time"}   # samples given as arrays: a file holds its own


def function(name):
    obj = accelcal
    for part in name.split("."):
        obj = getattr(obj, part)
    return obj


def options(words):
    p = build_parser()
    for w in words:
        p = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction)).choices[w]
    return {s for a in p._actions for s in a.option_strings}


def test_every_public_function_s_keywords_come_from_the_one_list():
    funcs = [n for n in accelcal.__all__ if inspect.isfunction(getattr(accelcal, n))]
    assert set(funcs) <= set(COMMANDS), "a public function this test does not know"
    for name, words in COMMANDS.items():
        params = [p for p in inspect.signature(function(name)).parameters if p != "cls"]
        assert not set(params) - set(KEYWORDS), (name, set(params) - set(KEYWORDS))
        # the old words are gone: one name for one thing
        assert not {"runtime_name", "say", "rate_hz", "out_csv"} & set(params), name
        have = options(words)
        for p in params:
            option = KEYWORDS[p][0]
            if option and option.startswith("-") and p not in IN_MEMORY_ONLY:
                assert option.split("/")[-1] in have, f"{name}({p}=): `accelcal " \
                    f"{' '.join(words)}` has no {option}"


def test_help_shows_each_keyword_with_its_unit():
    text = pydoc.render_doc(accelcal.calibrate, renderer=pydoc.plaintext)
    assert "rate: the sample rate, Hz [--rate]" in text
    assert "temperature, degC" in text and "(n, 3) in g" in text and "[--runtime]" in text
    text = pydoc.render_doc(accelcal.apply, renderer=pydoc.plaintext)
    assert "range_g: the device's full scale, g: 2, 4, 8 or 16 [--range]" in text


def test_the_api_reference_is_current():
    gen = runpy.run_path(str(ROOT / "tools" / "api_doc.py"))["render"]
    assert (ROOT / "docs" / "api.md").read_text() == gen(), \
        "docs/api.md is stale: run `.venv/bin/python tools/api_doc.py`"

