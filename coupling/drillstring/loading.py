"""Loading a drillstring: the TOML schema, the shipped examples and text or dict input."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from .validation import DrillStringError
from .section import Section
from .boundary import parse_boundary
from .drill_string import DrillString

__all__ = ["string_from_dict", "loads_string", "example_names", "example_path", "load_string"]

_DATA_DIR = Path(__file__).resolve().parent.parent / "data"
_TOP_KEYS = {"name", "description", "modal_damping_ratio", "mud_density", "max_element_length",
             "section", "boundaries"}
_SECTION_REQUIRED = ("name", "length", "od", "id")
_SECTION_OPTIONAL = ("youngs_modulus", "density", "linear_mass", "elements", "max_element_length",
                     "viscous_damping")
_BOUNDARY_KEYS = ("top", "bottom", "on_bottom", "off_bottom")


def string_from_dict(data: Mapping[str, Any], *, source: str = "<dict>") -> DrillString:
    """Build a :class:`DrillString` from the TOML data model.

    Raises
    ------
    DrillStringError
        Naming ``source``, the section (number and name), key, value and the
        allowed range.
    """
    if not isinstance(data, Mapping):
        raise DrillStringError(source, None, data, "top level must be a table")
    for key in data:
        if key not in _TOP_KEYS:
            raise DrillStringError(source, key, data[key],
                                   f"unknown top-level key; allowed keys {', '.join(sorted(_TOP_KEYS))}")
    raw_secs = data.get("section")
    if not isinstance(raw_secs, list) or not raw_secs:
        raise DrillStringError(source, "section", raw_secs, "at least one [[section]] table is required")
    sections = []
    for i, raw in enumerate(raw_secs, start=1):
        label = raw.get("name", "?") if isinstance(raw, Mapping) else "?"
        where = f"{source}: section #{i} '{label}'"
        if not isinstance(raw, Mapping):
            raise DrillStringError(where, None, raw, "each [[section]] must be a table")
        for key in raw:
            if key not in _SECTION_REQUIRED + _SECTION_OPTIONAL:
                raise DrillStringError(where, key, raw[key], "unknown key; allowed keys "
                                       + ", ".join(_SECTION_REQUIRED + _SECTION_OPTIONAL))
        for key in _SECTION_REQUIRED:
            if key not in raw:
                raise DrillStringError(where, key, None, "missing required key")
        try:
            sections.append(Section(**dict(raw)))
        except DrillStringError as err:
            raise DrillStringError(where, err.key, err.value, err.allowed) from None
    kw: dict[str, Any] = {k: data[k] for k in ("name", "description", "modal_damping_ratio",
                                               "mud_density", "max_element_length")
                          if k in data}
    kw.setdefault("name", Path(source).stem if source.endswith(".toml") else "drillstring")
    bnd = data.get("boundaries", {})
    if not isinstance(bnd, Mapping):
        raise DrillStringError(source, "boundaries", bnd, "must be a table")
    for key, val in bnd.items():
        if key not in _BOUNDARY_KEYS:
            raise DrillStringError(f"{source}: [boundaries]", key, val,
                                   "unknown key; allowed keys " + ", ".join(_BOUNDARY_KEYS))
        kw[key] = parse_boundary(val, where=f"{source}: [boundaries] {key}")
    try:
        return DrillString(tuple(sections), **kw)
    except DrillStringError as err:
        raise err.with_prefix(source) from None


def loads_string(text: str, *, source: str = "<string>") -> DrillString:
    """Parse TOML text (see :func:`string_from_dict`)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise DrillStringError(source, None, None, f"TOML syntax error: {err}") from None
    return string_from_dict(data, source=source)


def example_names() -> list[str]:
    """Names of the built-in example strings (``coupling/data/*.toml``)."""
    return sorted(p.stem for p in _DATA_DIR.glob("*.toml"))


def example_path(name: str) -> Path:
    """Path of a built-in example, e.g. ``field-2200m`` or ``lab``."""
    p = _DATA_DIR / f"{name}.toml"
    if not p.is_file():
        raise DrillStringError("example", "name", name, f"allowed values {', '.join(example_names())}")
    return p


def load_string(path_or_name: "str | Path") -> DrillString:
    """Load a string from a TOML file path or a built-in example name."""
    p = Path(path_or_name)
    if not p.is_file():
        if isinstance(path_or_name, str) and p.suffix == "" and path_or_name in example_names():
            p = example_path(path_or_name)
        else:
            raise DrillStringError(str(path_or_name), None, None,
                                   "no such file and not a built-in example; examples: "
                                   + ", ".join(example_names()))
    return loads_string(p.read_text(encoding="utf-8"), source=p.name)
