"""Following key paths through the config schema (pydantic models and their annotations).

A *location* is the path of keys and list indices pydantic reports for an error
(``("terrain", "rft", "Cm1")``, ``("pushes", 0, "force")``). These helpers find which
model or type sits at a location, so that errors can list the valid keys there and
suggest the closest one.
"""

from __future__ import annotations

import types
from typing import Annotated, Any, Mapping, Sequence, Union, get_args, get_origin

from pydantic import BaseModel


def strip_annotated(tp: Any) -> Any:
    """``Annotated[T, …]`` → ``T``; any other type unchanged."""
    if get_origin(tp) is Annotated:
        return get_args(tp)[0]
    return tp


def is_union(origin: Any) -> bool:
    """True for the origin of ``typing.Union[...]`` or of a PEP 604 ``X | Y``."""
    return origin is Union or origin is types.UnionType


def type_at(tp: Any, part: Any) -> Any:
    """The type one location element ``part`` below ``tp``, or None if there is none.

    Follows model fields (by name), list/tuple items (by index), dict values (by key) and
    unions (a discriminated member by its ``kind`` tag, else the first member that has
    ``part``).
    """
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        if isinstance(part, str) and part in tp.model_fields:
            return strip_annotated(tp.model_fields[part].annotation)
        return None
    origin = get_origin(tp)
    if origin in (list, tuple, Sequence) and isinstance(part, int):
        args = get_args(tp)
        return strip_annotated(args[0]) if args else None
    if origin in (dict, Mapping) and isinstance(part, str):
        args = get_args(tp)
        return strip_annotated(args[1]) if len(args) == 2 else None
    if is_union(origin):
        for arg in get_args(tp):
            arg = strip_annotated(arg)
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                kind = arg.model_fields.get("kind")
                if kind is not None and part in get_args(kind.annotation):
                    return arg
        for arg in get_args(tp):
            arg = strip_annotated(arg)
            found = type_at(arg, part)
            if found is not None:
                return found
    return None


def model_fields_at(model: type[BaseModel], loc: Sequence[Any]) -> list[str]:
    """Field names of the (nested) model addressed by ``loc`` — for did-you-mean hints.

    Args:
        model: the top-level config model.
        loc: a location below it (keys and list indices).

    Returns:
        The field names there, or ``[]`` if ``loc`` does not address a model.
    """
    current: Any = model
    for part in loc:
        current = type_at(current, part)
        if current is None:
            return []
    if isinstance(current, type) and issubclass(current, BaseModel):
        return list(current.model_fields)
    return []


def is_discriminator_tag(model: type[BaseModel], loc: Sequence[Any], i: int) -> bool:
    """True if ``loc[i]`` is a discriminated-union tag inserted by pydantic."""
    parent = model
    for part in loc[:i]:
        parent = type_at(parent, part)
        if parent is None:
            return False
    origin = get_origin(parent)
    if not is_union(origin):
        return False
    # only discriminated unions (members with a ``kind`` tag) insert the tag in the loc
    return any(isinstance(strip_annotated(a), type) and issubclass(strip_annotated(a), BaseModel)
               and "kind" in strip_annotated(a).model_fields for a in get_args(parent))


def fields_of(tp: Any) -> dict[str, Any] | None:
    """Field name → type of a model, or the merged fields of a union's members; else None.

    ``typing.Optional[X]`` / ``typing.Union`` are followed (their members' fields merged),
    which is why the scenario schema writes optional sections with ``typing``'s forms.
    """
    tp = strip_annotated(tp)
    if isinstance(tp, type) and issubclass(tp, BaseModel):
        return {k: strip_annotated(f.annotation) for k, f in tp.model_fields.items()}
    origin = get_origin(tp)
    if is_union(origin):
        merged: dict[str, Any] = {}
        for arg in get_args(tp):
            sub = fields_of(arg)
            if sub:
                for k, v in sub.items():
                    merged.setdefault(k, v)
        return merged or None
    return None


__all__ = ["strip_annotated", "is_union", "type_at", "model_fields_at", "is_discriminator_tag",
           "fields_of"]
