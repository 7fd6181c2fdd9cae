"""What every result object shares (pipeline/results.py), in the manner of lmfit's ModelResult:
the JSON record the command's --json prints, read as attributes as well as keys
(`r.status`, `r["status"]`), a short repr, summary(), to_dict() (exactly the JSON) and save();
and a calibration's parameters as a mapping with names, units and the fixed-point integers
beside (`r.params["kxx"].value`, `.unit`, `.int`)."""
from __future__ import annotations

import json
from typing import NamedTuple

# units of the paper's nine parameters (Farago 2024 eqs. 7-9): K is a gain, o an offset in g
BASE_UNITS = {"kxx": "1", "kyy": "1", "kzz": "1", "kxy": "1", "kxz": "1", "kyz": "1",
              "ox": "g", "oy": "g", "oz": "g"}


class Param(NamedTuple):
    """One fitted parameter: its name, decoded value (in unit), unit, and the integer the
    device holds (Q24, see `scale` of the record; None for a float method without one)."""
    name: str
    value: float
    unit: str
    int: int | None

    def __repr__(self):
        q = "" if self.int is None else f" (Q24 {self.int})"
        return f"<Param {self.name}={self.value:+.6g} {self.unit}{q}>"


def param_units(model: str | None) -> dict[str, str]:
    """Each parameter's unit for a model spec ("base", "base+temp_offset", ...): the base's
    from BASE_UNITS, an effect's from the catalogue (model/effects.py Effect.unit)."""
    units = dict(BASE_UNITS)
    if model and model != "base":
        from accelcal.model.effects import ModelSpec
        try:
            spec = ModelSpec.parse(model)
        except ValueError:   # a declared effect no longer registered: units unknown
            return units
        for e in spec.parts:
            units.update({n: e.unit for n in e.param_names})
    return units


class Params(dict):
    """A calibration's parameters by name (model order): each a Param with value, unit and the
    device's integer.  `valuesdict()` gives {name: value}, as lmfit's Parameters."""

    @classmethod
    def of(cls, values: dict | None, ints: dict | None, model: str | None) -> "Params":
        units = param_units(model)
        ints = ints or {}
        return cls({n: Param(n, float(v), units.get(n, "?"), ints.get(n))
                    for n, v in (values or {}).items()})

    def valuesdict(self) -> dict[str, float]:
        return {n: p.value for n, p in self.items()}

    def __repr__(self):
        return f"Params({', '.join(f'{n}={p.value:+.6g}' for n, p in self.items())})"

    def table(self) -> str:
        """One line per parameter: name, value, unit, the device's integer."""
        lines = [f"{'name':<10}{'value':>14}  {'unit':<10}{'Q24 int':>12}"]
        for n, p in self.items():
            q = "-" if p.int is None else str(p.int)
            lines.append(f"{n:<10}{p.value:>14.7g}  {p.unit:<10}{q:>12}")
        return "\n".join(lines)


class Record(dict):
    """A result: the command's JSON record (a dict, so `r["status"]` and json.dumps(r) work)
    whose keys also read as attributes (`r.status`, `r.error_after_mg`)."""

    def __getattr__(self, name: str):
        if name.startswith("_") or name not in self:
            raise AttributeError(f"{type(self).__name__} has no attribute {name!r}"
                                 + ("" if name.startswith("_") else
                                    f"; its fields: {', '.join(self)}"))
        return self[name]

    def __dir__(self):
        return sorted(set(super().__dir__()) | {k for k in self if k.isidentifier()})

    def to_dict(self) -> dict:
        """The record as plain JSON types: exactly what the command's --json prints."""
        return json.loads(self.to_json())

    def to_json(self) -> str:
        """The record as the command's --json prints it (one line)."""
        return json.dumps(self)

    def summary(self) -> str:
        """What the command prints (its report or table)."""
        return self.report() if hasattr(self, "report") and callable(self.report) else \
            self.table()

    def _repr_fields(self) -> str:
        return ""

    def __repr__(self):
        fields = self._repr_fields()
        return f"<{type(self).__name__}{' ' + fields if fields else ''}>"

    def _repr_pretty_(self, p, cycle):   # IPython: the short repr, not the dict
        p.text(repr(self))

    def save(self, path, force: bool = False) -> None:
        """The record as JSON (the command's --json), written whole or not at all, never over
        an input (force: replace an existing file)."""
        from accelcal.files.outputs import check_output, write_text
        check_output(path, [self.get("file") or self.get("input")], force, "save")
        write_text(path, json.dumps(self.to_dict(), indent=2) + "\n")
