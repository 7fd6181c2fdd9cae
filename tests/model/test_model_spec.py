"""A model spec holds its effect objects: names are resolved once, when it is made, so a spec
means what it meant then, whatever register() declares later; and a declared effect does not
outlive the test that declared it (conftest.catalogue_restored)."""
import pytest

from accelcal.model.declared import register
from accelcal.model.effects import CATALOGUE, ModelSpec

DECLARED = ("EFFECTS = [dict(name='sag', regressor='column:battery_v', unit='g/V', bound=0.01, "
            "explanation='The offset follows the battery.')]\n")


def test_a_spec_keeps_the_effects_it_was_made_with(tmp_path):
    spec = ModelSpec.parse("base+temp_offset+drift")
    assert spec.parts == (CATALOGUE["temp_offset"], CATALOGUE["drift"])
    assert spec.effects == ("temp_offset", "drift") and str(spec) == "base+temp_offset+drift"
    f = tmp_path / "effects.py"
    f.write_text(DECLARED)
    register(str(f))
    sag = ModelSpec.parse("base+sag")
    assert sag.columns == ("battery_v",) and sag.host_only == ("sag",)
    CATALOGUE.pop("sag")   # the catalogue changes; a spec made from it does not
    assert sag.effect("sag").declared_in == str(f) and sag.param_names[-3:] == ["sag_x", "sag_y",
                                                                                 "sag_z"]
    assert sag.with_effect("drift").effects == ("sag", "drift")
    assert sag.with_effect("drift").without("drift") == sag


def test_a_spec_from_its_own_catalogue():
    own = {"drift": CATALOGUE["drift"]}
    assert ModelSpec.parse("base+drift", own).parts == (CATALOGUE["drift"],)
    with pytest.raises(ValueError, match="unknown effect 'temp_offset' in model spec"):
        ModelSpec.parse("base+temp_offset", own)
    with pytest.raises(ValueError, match="unknown effect 'nope'"):
        ModelSpec(("nope",))


def test_declared_effects_do_not_leak_into_the_next_test():
    assert "sag" not in CATALOGUE and not any(e.declared_in for e in CATALOGUE.values())
