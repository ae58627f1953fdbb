"""TOML descriptions of tools, materials and machines: loading, units and validation.

A field's name carries its unit (``lead_mm``, ``moving_mass_kg``). A number is read in that unit; a
string "value unit" (``"0.2 in"``, ``"5 kg"``) is converted, and a unit of the wrong kind is refused.
Every refusal is a `ConfigError` naming the field (dotted path), the value and the rule, plus the file.
Unknown fields are refused too, with the closest known name (a misspelt unit suffix is a common slip).
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from .errors import ConfigError

# unit suffix of a field name -> (what it measures, {unit spelling: factor to the suffix unit})
_LENGTH = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "um": 1e-3, "µm": 1e-3, "in": 25.4, "inch": 25.4, "ft": 304.8}
SUFFIX_UNITS: dict[str, tuple[str, dict[str, float]]] = {
    "mm": ("length", _LENGTH),
    "kg": ("mass", {"kg": 1.0, "g": 1e-3, "lb": 0.45359237}),
    "N": ("force", {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605}),
    "W": ("power", {"W": 1.0, "kW": 1e3, "hp": 745.69987158}),
    "rpm": ("rotational speed", {"rpm": 1.0, "rev/min": 1.0, "krpm": 1e3}),
    "deg": ("angle", {"deg": 1.0, "°": 1.0, "rad": 180.0 / math.pi}),
    "A": ("current", {"A": 1.0, "mA": 1e-3}),
    "V": ("voltage", {"V": 1.0, "mV": 1e-3}),
    "ohm": ("resistance", {"ohm": 1.0, "Ω": 1.0, "mohm": 1e-3}),
    "H": ("inductance", {"H": 1.0, "mH": 1e-3, "uH": 1e-6, "µH": 1e-6}),
    "Nm": ("torque", {"Nm": 1.0, "N*m": 1.0, "N·m": 1.0, "Ncm": 1e-2, "N*cm": 1e-2, "ozf*in": 7.0615518e-3}),
    "Nm_per_A": ("torque constant", {"Nm/A": 1.0, "N*m/A": 1.0, "Ncm/A": 1e-2}),
    "kgm2": ("moment of inertia", {"kg*m^2": 1.0, "kgm2": 1.0, "g*cm^2": 1e-7, "kg*cm^2": 1e-4}),
    "N_per_mm": ("stiffness or force per length", {"N/mm": 1.0, "N/um": 1e3, "N/µm": 1e3, "N/m": 1e-3}),
    "N_s_per_mm": ("viscous friction", {"N*s/mm": 1.0, "N*s/m": 1e-3}),
    "mm_min": ("feed rate", {"mm/min": 1.0, "mm/s": 60.0, "m/min": 1e3, "in/min": 25.4, "ipm": 25.4}),
    "mm_s2": ("acceleration", {"mm/s^2": 1.0, "mm/s2": 1.0, "m/s^2": 1e3, "m/s2": 1e3, "in/s^2": 25.4}),
    "mm3_min": ("removal rate", {"mm^3/min": 1.0, "cm^3/min": 1e3}),
    "MPa": ("stress", {"MPa": 1.0, "GPa": 1e3, "N/mm^2": 1.0, "N/mm2": 1.0, "psi": 6.894757e-3, "ksi": 6.894757}),
    "N_mm2": ("specific cutting force", {"N/mm^2": 1.0, "N/mm2": 1.0, "MPa": 1.0, "GPa": 1e3, "N/m^2": 1e-6}),
    "m_min": ("surface speed", {"m/min": 1.0, "SFM": 0.3048, "sfm": 0.3048, "ft/min": 0.3048}),
    "Hz": ("frequency", {"Hz": 1.0, "kHz": 1e3}),
    "s": ("time", {"s": 1.0, "ms": 1e-3}),
}
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)?\s*$")
_MISSING = object()


def _suffix(key: str) -> str | None:
    """The longest unit suffix of a field name, or None for dimensionless fields."""
    best = None
    for s in SUFFIX_UNITS:
        if key.endswith("_" + s) and (best is None or len(s) > len(best)):
            best = s
    return best


def load_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors become a ConfigError naming the file and position."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("<file>", p.name, f"not valid TOML ({exc})", file=str(p)) from None


def builtin_names(kind: str) -> list[str]:
    """Names of the built-in descriptions of a kind ('materials', 'machines')."""
    folder = resources.files("millpost") / "data" / kind
    return sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".toml"))


def load_description(kind: str, name_or_path: str | Path) -> tuple[dict[str, Any], str]:
    """(parsed TOML, file name) of a built-in description by name, or of a file by path."""
    path = resolve(kind, name_or_path)
    return load_toml(path), str(path)


def resolve(kind: str, name_or_path: str | Path) -> Path:
    """A built-in description by name, or a file by path; unknown names list the built-ins."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        if not p.is_file():
            raise ConfigError(kind[:-1], str(name_or_path), "file not found")
        return p
    builtin = resources.files("millpost") / "data" / kind / f"{name_or_path}.toml"
    if not builtin.is_file():
        raise ConfigError(kind[:-1], str(name_or_path),
                          f"unknown {kind[:-1]}; built-in: {', '.join(builtin_names(kind))}, or give a .toml path")
    return Path(str(builtin))


def is_number(value: object) -> bool:
    """A finite int or float (TOML's nan, inf and booleans are not numbers here)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def quantity(value: Any, suffix: str | None, field: str, *, file: str | None = None) -> float:
    """A finite float in the unit named by `suffix` (a key of SUFFIX_UNITS, None = dimensionless) from a
    number or a "value unit" string; ConfigError(field, value, rule) otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ConfigError(field, value, "must be a number", file=file)
    if isinstance(value, str):
        m = _QUANTITY.match(value)
        if not m:
            raise ConfigError(field, value, "must be a number or 'value unit'", file=file)
        number, unit = float(m.group(1)), (m.group(2) or "").replace(" ", "")
        if unit:
            if suffix is None:
                raise ConfigError(field, value, "is dimensionless; give a plain number", file=file)
            what, table = SUFFIX_UNITS[suffix]
            if unit not in table:
                raise ConfigError(field, value, f"unit {unit!r} is not a {what} unit; use {', '.join(table)}",
                                  file=file)
            number *= table[unit]
        value = number
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(field, value, "must be finite", file=file)
    return value


class Table:
    """A validated view of one TOML table. Reads fields with unit conversion and range rules, tracks
    which fields were read, and `done()` refuses the rest as unknown."""

    def __init__(self, data: Any, name: str = "", file: str | None = None) -> None:
        if not isinstance(data, dict):
            raise ConfigError(name or "<root>", data, "must be a table", file=file)
        self.data, self.name, self.file = data, name, file
        self._read: set[str] = set()

    def _field(self, key: str) -> str:
        return f"{self.name}.{key}" if self.name else key

    def fail(self, key: str, value: object, rule: str) -> ConfigError:
        return ConfigError(self._field(key), value, rule, file=self.file)

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default: Any) -> Any:
        """The field as written (no unit or type check), marked read; `default` when absent (required
        without one)."""
        self._read.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise self.fail(key, None, "is required")
            return default
        return self.data[key]

    def _convert(self, key: str, value: Any) -> float:
        return quantity(value, _suffix(key), self._field(key), file=self.file)

    def number(self, key: str, default: Any = _MISSING, *, gt: float | None = None, ge: float | None = None,
               lt: float | None = None, le: float | None = None) -> Any:
        """A float in the unit named by the key's suffix, checked against bounds."""
        raw = self.raw(key, default)
        if raw is default and key not in self.data:
            return default
        v = self._convert(key, raw)
        unit = _suffix(key) or ""
        for bound, ok, word in ((gt, lambda b: v > b, ">"), (ge, lambda b: v >= b, ">="),
                                (lt, lambda b: v < b, "<"), (le, lambda b: v <= b, "<=")):
            if bound is not None and not ok(bound):
                raise self.fail(key, raw, f"must be {word} {bound:g} {unit}".rstrip())
        return v

    def numbers(self, key: str, default: Any = _MISSING, *, gt: float | None = None, ge: float | None = None,
                length: int | None = None) -> Any:
        """A list of floats (same unit rules as `number`)."""
        raw = self.raw(key, default)
        if raw is default and key not in self.data:
            return default
        if not isinstance(raw, list) or not raw:
            raise self.fail(key, raw, "must be a non-empty list of numbers")
        if length is not None and len(raw) != length:
            raise self.fail(key, raw, f"must have {length} entries")
        out = []
        for i, item in enumerate(raw):
            v = self._convert(key, item)
            if (gt is not None and not v > gt) or (ge is not None and not v >= ge):
                rule = f"> {gt:g}" if gt is not None else f">= {ge:g}"
                raise self.fail(f"{key}[{i}]", item, f"must be {rule}")
            out.append(v)
        return tuple(out)

    def integer(self, key: str, default: Any = _MISSING, *, ge: int | None = None, le: int | None = None) -> Any:
        raw = self.raw(key, default)
        if raw is default and key not in self.data:
            return default
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise self.fail(key, raw, "must be an integer")
        if (ge is not None and raw < ge) or (le is not None and raw > le):
            raise self.fail(key, raw, f"must be in [{ge}, {le}]")
        return raw

    def string(self, key: str, default: Any = _MISSING, *, choices: tuple[str, ...] | None = None) -> Any:
        raw = self.raw(key, default)
        if raw is default and key not in self.data:
            return default
        if not isinstance(raw, str):
            raise self.fail(key, raw, "must be a string")
        if choices is not None and raw not in choices:
            raise self.fail(key, raw, f"must be one of {', '.join(choices)}")
        return raw

    def table(self, key: str, default: Any = _MISSING) -> Any:
        raw = self.raw(key, default)
        if raw is default and key not in self.data:
            return default
        return Table(raw, self._field(key), self.file)

    def tables(self, key: str) -> list["Table"]:
        """A non-empty list of tables (a TOML array of inline tables, or [[key]] tables), each named
        key[i] in a refusal."""
        raw = self.raw(key, _MISSING)
        if not isinstance(raw, list) or not raw:
            raise self.fail(key, raw, "must be a non-empty list of tables, e.g. [{...}, {...}]")
        return [Table(item, f"{self._field(key)}[{i}]", self.file) for i, item in enumerate(raw)]

    def done(self, also_known: tuple[str, ...] = ()) -> None:
        """Refuse fields nobody read (misspelt names and wrong unit suffixes land here). `also_known`
        lists optional fields that were absent, so that a misspelling of one of them gets its hint."""
        known = sorted(self._read | set(also_known))
        for key in self.data:
            if key not in known:
                close = difflib.get_close_matches(key, known, n=1, cutoff=0.5)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise self.fail(key, self.data[key], f"unknown field{hint} (known: {', '.join(known)})")


def dump_toml(data: dict[str, Any]) -> str:
    """TOML text of a description: strings, numbers, booleans, lists of those, and nested tables (the
    subset the descriptions use; `load_toml` reads it back to the same dict)."""
    out: list[str] = []

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            if isinstance(v, float) and not math.isfinite(v):
                raise ConfigError("<toml>", v, "a description holds finite numbers only")
            return repr(v)  # shortest text that reads back to the same number
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        raise ConfigError("<toml>", v, "cannot be written as TOML")

    def table(prefix: str, d: dict[str, Any]) -> None:
        scalars = {k: v for k, v in d.items() if not isinstance(v, dict)}
        if prefix and (scalars or not d):
            out.append(f"\n[{prefix}]")
        out.extend(f"{k} = {value(v)}" for k, v in scalars.items())
        for k, v in d.items():
            if isinstance(v, dict):
                table(f"{prefix}.{k}" if prefix else k, v)

    table("", data)
    return "\n".join(out).lstrip("\n") + "\n"
