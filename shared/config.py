"""Build frozen configuration dataclasses from TOML and plain mappings, refusing unknown keys and wrong types.

One mechanism for every component: a config class is a frozen, slotted dataclass whose fields carry units in their
names and whose ``__post_init__`` checks ranges with the `check_*` helpers below. `from_mapping` turns a mapping
(a TOML table) into such a class, recursing into nested dataclass fields, and names the file and the dotted key in
every error.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from enum import Enum
from pathlib import Path
from typing import Any, TypeVar

from ropecam.shared.errors import ConfigError

__all__ = [
    "check_finite",
    "check_in",
    "check_positive",
    "check_range",
    "check_readout",
    "from_mapping",
    "load_tables",
    "load_toml",
    "read_toml",
]

T = TypeVar("T")


def check_finite(name: str, value: float) -> None:
    """Raise `ConfigError` unless `value` is a finite number."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{name} must be a finite number, got {value!r}")


def check_positive(name: str, value: float) -> None:
    """Raise `ConfigError` unless `value` is a finite number > 0."""
    check_finite(name, value)
    if value <= 0:
        raise ConfigError(f"{name} must be > 0, got {value!r}")


def check_range(name: str, value: float, low: float, high: float) -> None:
    """Raise `ConfigError` unless ``low <= value <= high``."""
    check_finite(name, value)
    if not low <= value <= high:
        raise ConfigError(f"{name} must be in [{low}, {high}], got {value!r}")


def check_readout(name: str, readout_us: object, fps: float | None) -> None:
    """Raise `ConfigError` unless `readout_us` (a rolling shutter's readout time in microseconds, 0 = global
    shutter) is an integer in [0, frame period]; the period is checked only when `fps` is known."""
    if isinstance(readout_us, bool) or not isinstance(readout_us, int):
        raise ConfigError(f"{name} must be an integer number of microseconds (0 = global shutter), got {readout_us!r}")
    if readout_us < 0:
        raise ConfigError(f"{name} must be >= 0 (0 = global shutter), got {readout_us}")
    if fps is not None and fps > 0 and readout_us > 1e6 / fps:
        raise ConfigError(
            f"{name} is {readout_us} us, longer than the frame period {1e6 / fps:.0f} us at {fps:g} FPS; "
            "a sensor reads its rows out within one frame"
        )


def check_in(name: str, value: object, allowed: typing.Iterable[object]) -> None:
    """Raise `ConfigError` unless `value` is one of `allowed`."""
    allowed = tuple(allowed)
    if value not in allowed:
        raise ConfigError(f"{name} must be one of {', '.join(repr(a) for a in allowed)}, got {value!r}")


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; a missing or malformed file raises `ConfigError` naming it."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: config file not found") from exc
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config file: {exc.strerror}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc


def load_toml(path: str | Path, cls: type[T], section: str | None = None) -> T:
    """Load `cls` from a TOML file, optionally from one top-level table `section`.

    Parameters
    ----------
    path
        The TOML file.
    cls
        A (frozen) dataclass type.
    section
        Name of a top-level table to read; the whole file when None. A missing table gives the defaults. Other
        tables are not checked here: an application reading a multi-table file uses `load_tables`, which refuses
        unknown (e.g. misspelled) tables.

    Raises
    ------
    ConfigError
        The file is missing or malformed, a key is unknown, a value has the wrong type or is out of range.
    """
    data: Any = read_toml(path)
    where = str(path)
    if section is not None:
        data = data.get(section, {})
        where = f"{path} [{section}]"
    return from_mapping(cls, data, where=where)


def load_tables(path: str | Path | None, tables: dict[str, type], **overrides: dict[str, Any]) -> dict[str, Any]:
    """Load a TOML file whose top-level tables are component configs; an unknown table is an error.

    Parameters
    ----------
    path
        The file; None gives every component its defaults (plus overrides).
    tables
        Table name -> dataclass type, e.g. ``{"rope": RopeConfig, "solver": SolverConfig}``.
    overrides
        Per table, values that replace the file's (None values are ignored), e.g. from command-line options.

    Returns
    -------
    dict
        Table name -> config instance, for every name in `tables` (missing tables get defaults).

    Raises
    ------
    ConfigError
        The file is missing or malformed, a table or key is unknown, a value is wrong (naming file, table, key).
    """
    data: dict[str, Any] = read_toml(path) if path is not None else {}
    where = str(path) if path is not None else "command line"
    unknown = sorted(set(data) - set(tables))
    if unknown:
        allowed = ", ".join(f"[{name}]" for name in tables)
        raise ConfigError(f"{where}: unknown table [{unknown[0]}] (allowed: {allowed})")
    return {
        name: from_mapping(cls, data.get(name, {}), where=f"{where} [{name}]", **overrides.get(name, {}))
        for name, cls in tables.items()
    }


def from_mapping(cls: type[T], data: Mapping[str, Any], where: str = "config", **overrides: Any) -> T:
    """Build dataclass `cls` from `data`; `overrides` (not None) replace values from `data`.

    Raises
    ------
    ConfigError
        An unknown key (with the keys that are allowed), a wrong type, or a value `cls` rejects.
    """
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"cls must be a dataclass type, got {cls!r}")
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a table, got {type(data).__name__} {data!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    merged = dict(data)
    merged.update({k: v for k, v in overrides.items() if v is not None})
    unknown = sorted(set(merged) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(fields))})")
    kwargs = {name: _convert(hints[name], value, f"{where}.{name}") for name, value in merged.items()}
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def _convert(hint: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if hint is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where}: {value!r} matches none of {hint}")
    if origin is typing.Literal:
        if value not in args:
            raise ConfigError(f"{where}: must be one of {', '.join(repr(a) for a in args)}, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where}: expected an array, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}: {value!r}")
        return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return from_mapping(hint, value, where=where)
    if isinstance(hint, type) and issubclass(hint, Enum):
        try:
            return hint(value)
        except ValueError as exc:
            allowed = ", ".join(repr(m.value) for m in hint)
            raise ConfigError(f"{where}: must be one of {allowed}, got {value!r}") from exc
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    if hint is Path:
        if not isinstance(value, str | Path):
            raise ConfigError(f"{where}: expected a path string, got {value!r}")
        return Path(value)
    return value
