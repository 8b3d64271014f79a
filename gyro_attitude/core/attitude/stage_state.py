"""What the stages whose state is arrays (stepped by the compiled chain, core/jit.py) share."""

from __future__ import annotations

__all__ = ["time_base"]


def time_base(ints: str, last: int, has: int) -> property:
    """``last_t_ns`` of a stage whose int state array is attribute ``ints``, the last stamp at
    slot ``last`` and whether there is one at ``has``: read as an int or None; only None is set
    from outside (a new time base: the stage starts its filters again)."""

    def get(self) -> int | None:
        a = getattr(self, ints)
        return int(a[last]) if a[has] else None

    def put(self, value) -> None:
        if value is not None:
            raise ValueError("last_t_ns is set by the samples; assign None to restart")
        getattr(self, ints)[has] = 0

    return property(get, put, doc="the last sample's stamp (ns), None for a new time base")
