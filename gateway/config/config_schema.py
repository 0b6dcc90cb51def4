"""Build typed config dataclasses from TOML tables, with messages that name the problem.

One generic validator serves every section: it checks unknown keys, types and 3-vectors,
and reports ``file: [section] key = value: expected ...`` so a user can fix the file.
"""

from __future__ import annotations

import ast
import dataclasses
import enum
import inspect
import io
import math
import sys
import textwrap
import tokenize
import types
import typing
from pathlib import Path
from typing import Any, TypeVar, Union

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

T = TypeVar("T")


class ConfigError(ValueError):
    """A config file or value is wrong; the message says which key, the value and what fits."""


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; an unreadable or invalid file is a ConfigError naming the file."""
    try:
        with Path(path).open("rb") as f:
            return tomllib.load(f)
    except OSError as err:
        raise ConfigError(f"{path}: cannot read config file: {err.strerror}") from None
    except UnicodeDecodeError as err:
        raise ConfigError(
            f"{path}: not a text file (byte 0x{err.object[err.start]:02X} at offset "
            f"{err.start} is not UTF-8); expected a TOML config"
        ) from None
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML: {err}") from None


def _describe(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in typing.get_args(tp))
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_describe(args[0])}"
        return f"a list of {len(args)} numbers" if args else "a list"
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if _is_namedtuple(tp):
        return f"a list [{', '.join(tp._fields)}]"
    if tp is type(None):
        return "absent"
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )


def _is_namedtuple(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, tuple) and hasattr(tp, "_fields")


def _convert(value: Any, tp: Any, where: str) -> Any:
    """Return ``value`` as type ``tp`` or raise ConfigError naming ``where``."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        for arg in typing.get_args(tp):
            if arg is type(None):
                continue
            try:
                return _convert(value, arg, where)
            except ConfigError:
                pass
        raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")
    if origin is typing.Literal:
        if value in typing.get_args(tp):
            return value
        raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")
    if _is_namedtuple(tp):
        hints = typing.get_type_hints(tp)
        if not isinstance(value, list | tuple) or len(value) != len(tp._fields):
            raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")
        items = zip(tp._fields, value, strict=True)
        return tp(*(_convert(v, hints[name], f"{where}.{name}") for name, v in items))
    if origin is tuple and len(typing.get_args(tp)) == 2 and typing.get_args(tp)[1] is Ellipsis:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")
        item = typing.get_args(tp)[0]
        return tuple(_convert(v, item, f"{where}[{i}]") for i, v in enumerate(value))
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list | tuple) or len(value) != len(args):
            raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")
        pairs = enumerate(zip(value, args, strict=True))
        return tuple(_convert(v, a, f"{where}[{i}]") for i, (v, a) in pairs)
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        if not isinstance(value, dict):
            raise ConfigError(f"{where} = {value!r}: expected a table [{where}]")
        return from_table(tp, value, where)
    if tp is float and isinstance(value, int | float) and not isinstance(value, bool):
        if not math.isfinite(value):  # TOML has nan and inf: no setting means either
            raise ConfigError(f"{where} = {value!r}: expected a finite number")
        return float(value)
    if tp is int and isinstance(value, int) and not isinstance(value, bool):
        return value
    if tp in (bool, str) and isinstance(value, tp):
        return value
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            choices = ", ".join(repr(m.value) for m in list(tp))
            raise ConfigError(f"{where} = {value!r}: expected one of {choices}") from None
    raise ConfigError(f"{where} = {value!r}: expected {_describe(tp)}")


def from_table(cls: type[T], table: dict[str, Any], where: str = "", base: T | None = None) -> T:
    """Instantiate dataclass ``cls`` from a TOML table; unknown keys are errors that name them.

    Keys absent from the table keep the field defaults, or the values of ``base`` if given.

    Fields may carry ``metadata={"check": fn}`` where ``fn(value)`` returns an error text
    (what is expected) or None; it runs after type conversion.
    """
    hints = typing.get_type_hints(cls)
    known = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    prefix = f"{where}." if where else ""
    for key in table:
        if key not in known:
            raise ConfigError(
                f"unknown key {prefix}{key}: expected one of {', '.join(sorted(known))}"
            )
    kwargs = {}
    for key, value in table.items():
        converted = _convert(value, hints[key], f"{prefix}{key}")
        check = known[key].metadata.get("check")
        if check is not None and (problem := check(converted)):
            raise ConfigError(f"{prefix}{key} = {value!r}: expected {problem}")
        kwargs[key] = converted
    try:
        return dataclasses.replace(base, **kwargs) if base is not None else cls(**kwargs)  # type: ignore[type-var]
    except ValueError as err:  # a dataclass's own __post_init__ check
        raise ConfigError(f"[{where}] {err}") from None


def in_range(lo: float, hi: float) -> dict[str, Any]:
    """Field metadata: the value (or every element) must lie in [lo, hi]."""

    def check(value: Any) -> str | None:
        values = value if isinstance(value, tuple) else (value,)
        return None if all(lo <= v <= hi for v in values) else f"a value in [{lo}, {hi}]"

    return {"check": check}


def source_comments(cls: type) -> dict[str, str]:
    """The comment of each field in the source of class ``cls``: its trailing ``# ...``, else
    the comment lines heading its group (fields with no blank line between).

    The engine tunings document their fields as code comments, not field metadata; this is
    how ``navgw config --example`` shows them. Rules (``# --- timing ---``) title a part of the
    class, not a field.
    """
    source = textwrap.dedent(inspect.getsource(cls))
    comments = {
        tok.start[0]: tok.string.lstrip("#").strip()
        for tok in tokenize.generate_tokens(io.StringIO(source).readline)
        if tok.type == tokenize.COMMENT
    }
    body = typing.cast(ast.ClassDef, ast.parse(source).body[0]).body
    fields = {node.lineno: node for node in body if isinstance(node, ast.AnnAssign)}
    covered = {n for node in fields.values() for n in range(node.lineno, _end(node) + 1)}
    docs: dict[str, str] = {}
    heading: list[str] = []  # the comment lines heading the current group of fields
    previous_is_heading = False
    for number, line in enumerate(source.splitlines(), start=1):
        alone = number in comments and number not in covered and line.lstrip().startswith("#")
        note = alone and not comments[number].startswith("---")
        if number in fields:
            node = fields[number]
            own = [comments[n] for n in range(number, _end(node) + 1) if n in comments]
            docs[ast.unparse(node.target)] = " ".join(own or heading)
        elif note:
            heading = [*heading, comments[number]] if previous_is_heading else [comments[number]]
        elif number not in covered:
            heading = []
        previous_is_heading = note
    return docs


def _end(node: ast.stmt) -> int:
    return node.end_lineno or node.lineno
