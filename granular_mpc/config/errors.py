"""Validation with one clear error: pydantic's errors → one :class:`ConfigError`.

The error names the dotted key path, the offending value, what is allowed and — for a
misspelt key — the closest valid key. The data-format checks word their ``meta.yaml``
problems the same way (:func:`format_location`, :func:`model_fields_at`).
"""

from __future__ import annotations

import difflib
from typing import Any, Sequence

from pydantic import BaseModel, ValidationError

from ..exceptions import ConfigError
from .schema_walk import is_discriminator_tag, model_fields_at


def format_location(loc: Sequence[Any]) -> str:
    """A pydantic location as a dotted key path: ``("pushes", 0, "force")`` → ``pushes[0].force``."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def validate(model: type[BaseModel], data: Any, *, source: str = "", prefix: str = ""):
    """Validate ``data`` against ``model``; raise one ConfigError listing every problem.

    Args:
        model: the config model.
        data: plain data (mappings, lists, numbers, strings).
        source: the file the data came from (kept in the error).
        prefix: key path prepended to every reported key (e.g. ``"terrain"``).

    Returns:
        The validated, frozen config object.

    Raises:
        ConfigError: naming the first problem's key, value and allowed values; its message
            lists every problem.
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        messages = []
        first_key = ""
        first_value: Any = None
        allowed_first = ""
        for err in exc.errors():
            loc = list(err["loc"])
            # drop discriminator tags (e.g. 'granular') that pydantic inserts in the loc
            clean = [p for i, p in enumerate(loc) if not is_discriminator_tag(model, loc, i)]
            key = format_location(([prefix] if prefix else []) + clean)
            typ = err["type"]
            allowed = ""
            if typ == "extra_forbidden":
                valid = model_fields_at(model, [p for p in loc[:-1]])
                close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.5)
                hint = f"; did you mean '{close[0]}'?" if close else ""
                msg = f"unknown key '{loc[-1]}'{hint}"
                allowed = ", ".join(valid)
            elif typ == "missing":
                msg = "required key is missing"
            elif typ == "union_tag_invalid":
                ctx = err.get("ctx", {})
                msg = f"unknown kind {ctx.get('tag')!r}"
                allowed = str(ctx.get("expected_tags", ""))
            else:
                msg = f"{err['msg']} (got {err.get('input')!r})"
            if not first_key:
                first_key, first_value, allowed_first = key, err.get("input"), allowed
            line = f"{key}: {msg}" if key else msg
            if allowed and typ != "extra_forbidden":
                line += f" (allowed: {allowed})"
            elif allowed:
                line += f" (valid keys here: {allowed})"
            messages.append(line)
        text = messages[0] if len(messages) == 1 else (
            f"{len(messages)} problems:\n  - " + "\n  - ".join(messages))
        # the allowed values are already in the text: keep them as data only
        err = ConfigError(text, value=first_value, source=source)
        err.allowed = allowed_first
        err.key = first_key
        raise err from None


__all__ = ["format_location", "model_fields_at", "validate"]
