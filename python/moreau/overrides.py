"""Overrides as the scene format takes them, for runs here (moreau.local) and on a server (moreau.client):
Python values as JSON text, a NaN or an infinity (which JSON has not) refused by the pointer of where it
is, and `set` mappings as the command line's PATH=VALUE assignments."""

from __future__ import annotations

import json
import math
import numbers
from typing import Any, List, Mapping, Optional, Sequence, Union

from .errors import SceneError

Sets = Union[None, Mapping[str, Any], Sequence[str]]


def _json_default(value: Any) -> Any:
    # numpy's scalars and arrays (a sweep over np.linspace or np.arange) as the JSON numbers and lists they are.
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError("%s is not a JSON value" % type(value).__name__)


def _non_finite(value: Any, pointer: str) -> Optional[str]:
    """The JSON pointer of the first number in `value` that is not finite, or None."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and not math.isfinite(value):
        return pointer or "/"
    if isinstance(value, Mapping):
        items = ((str(k).replace("~", "~0").replace("/", "~1"), v) for k, v in value.items())
    elif isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        items = ((str(i), v) for i, v in enumerate(value.tolist() if hasattr(value, "tolist") else value))
    else:
        return None
    for key, v in items:
        found = _non_finite(v, pointer + "/" + key)
        if found:
            return found
    return None


def json_text(value: Any, pointer: str = "") -> str:
    """`value` as JSON text; a NaN or an infinity, which JSON has not, is a SceneError naming where it is."""
    try:
        return json.dumps(value, allow_nan=False, default=_json_default)
    except ValueError:
        where = _non_finite(value, pointer) or pointer or "/"
        raise SceneError("%s: not a finite number (JSON has no NaN or infinity)" % where, where,
                         "not a finite number (JSON has no NaN or infinity)") from None
    except RecursionError:
        where = pointer or "/"
        raise SceneError("%s: nested too deeply to be a scene" % where, where, "nested too deeply to be a scene") from None


def _pointer_of(path: str) -> str:
    """A `set` path as the JSON pointer it names: "/integrator/h" as it is, "integrator.h" as /integrator/h."""
    return path if path.startswith("/") else "/" + "/".join(part.replace("~", "~0").replace("/", "~1") for part in path.split("."))


def set_list(sets: Sets) -> List[str]:
    """`set` as the command line's PATH=VALUE assignments: a mapping's values are written as JSON, so
    1e-4 stays the number it is (repr round-trips) and "sin(q1)" a string."""
    if sets is None:
        return []
    if isinstance(sets, Mapping):
        return ["%s=%s" % (path, json_text(value, _pointer_of(path))) for path, value in sets.items()]
    if isinstance(sets, str):
        raise TypeError("set: a mapping {'integrator.h': 1e-4} or a list of 'PATH=VALUE' strings, not one string")
    return [str(s) for s in sets]
