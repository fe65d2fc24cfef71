"""Frozen result records and their JSON form (the base of every diagnosis record).

A record is a frozen dataclass whose field names are its JSON keys. :class:`Record` gives
it ``to_dict`` (nested records, tuples and mappings turned into JSON types, in field
order) and ``from_dict`` (the reverse, driven by the field types), so a stage result, the
``Diagnosis`` and ``diagnosis.json`` stay one thing. Field metadata :data:`OMIT_NONE` /
:data:`OMIT_EMPTY` leaves a key out of the JSON when the value is ``None`` / empty (keys
that only some entries have).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any, Mapping, TypeVar, Union

#: field metadata: leave the key out of the JSON when the value is None
OMIT_NONE = {"omit_none": True}
#: field metadata: leave the key out of the JSON when the value is empty
OMIT_EMPTY = {"omit_empty": True}
#: field metadata: not part of the JSON form (e.g. where a result was written)
NOT_JSON = {"json": False}

R = TypeVar("R", bound="Record")


def to_jsonable(value: Any) -> Any:
    """``value`` with records → dicts, tuples → lists, mappings → dicts (recursively)."""
    if isinstance(value, Record):
        return value.to_dict()
    if isinstance(value, Mapping):
        return {k: to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (tuple, list)):
        return [to_jsonable(v) for v in value]
    return value


def from_jsonable(tp: Any, data: Any) -> Any:
    """``data`` (parsed JSON) as type ``tp``: records, ``tuple[X, ...]``, ``Mapping[str, X]``,
    ``X | None``, ``float`` (``None`` → NaN: JSON has no NaN), other scalars as they are."""
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if data is None:
            return None
        if len(args) == 1:
            return from_jsonable(args[0], data)
        return data
    if isinstance(tp, type) and issubclass(tp, Record):
        return tp.from_dict(data)
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_jsonable(args[0], v) for v in data)
        return tuple(from_jsonable(a, v) for a, v in zip(args, data))
    if origin in (Mapping, dict, typing.Mapping) or (origin is not None and isinstance(origin, type)
                                                      and issubclass(origin, Mapping)):
        _, vt = typing.get_args(tp)
        return {k: from_jsonable(vt, v) for k, v in data.items()}
    if tp is float:
        return float("nan") if data is None else float(data)
    return data


class Record:
    """Base of the frozen diagnosis records: ``to_dict`` / ``from_dict`` by field, and a
    read-only ``record["key"]`` view of ``to_dict()`` for scripts written against the
    former dict results."""

    def to_dict(self) -> dict:
        """JSON-ready dict (keys = field names, in field order)."""
        out = {}
        for f in dataclasses.fields(self):
            if f.metadata.get("json", True) is False:
                continue
            v = getattr(self, f.name)
            if f.metadata.get("omit_none") and v is None:
                continue
            if f.metadata.get("omit_empty") and not v:
                continue
            out[f.name] = to_jsonable(v)
        return out

    @classmethod
    def from_dict(cls: type[R], data: Mapping[str, Any]) -> R:
        """The record from its :meth:`to_dict` form (missing optional keys → defaults)."""
        hints = typing.get_type_hints(cls)
        kw = {}
        for f in dataclasses.fields(cls):
            if f.name in data and f.metadata.get("json", True) is not False:
                kw[f.name] = from_jsonable(hints[f.name], data[f.name])
        return cls(**kw)

    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    def get(self, key: str, default: Any = None) -> Any:
        """``to_dict().get(key, default)``."""
        return self.to_dict().get(key, default)


__all__ = ["Record", "OMIT_NONE", "OMIT_EMPTY", "NOT_JSON", "to_jsonable", "from_jsonable"]
