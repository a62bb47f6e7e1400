"""What a view is given: one draw's Trace, a DrawResult drawn with ``trace=True``, or a list of them (a scene's
``results``, in the order drawn). :func:`traced_draws` takes any of these and says which item is not a trace.

The explorer page, the overlays and the diff of two draws all take their draws so.
"""
from __future__ import annotations

from typing import Any, List, Tuple

__all__ = ["traced_draws"]


def traced_draws(items: Any, what: str) -> List[Tuple[Any, Any]]:
    """(item, trace) of each draw in ``items``: a Trace, a DrawResult, or a list or tuple of either.

    A TypeError names ``what`` (the view asking) and the item that holds no trace; a ValueError
    an empty list.
    """
    listed = list(items) if isinstance(items, (list, tuple)) else [items]
    out = []
    for k, item in enumerate(listed):
        trace = getattr(item, "trace", None) if hasattr(item, "program") else item
        if trace is None or not hasattr(trace, "pixel_history"):
            raise TypeError(f"{what}: item {k}: expected a Trace or a DrawResult drawn with trace=True, got "
                            f"{type(item).__name__}")
        out.append((item, trace))
    if not out:
        raise ValueError(f"{what}: no draws (an empty list)")
    return out
