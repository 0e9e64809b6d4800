"""Explicit, collective release of PETSc objects: no ``__del__`` (see linalg/base.py).

:func:`destroy_attributes` destroys an owner's PETSc objects once; :class:`Releasable` gives a
class with a ``destroy()`` method the context-manager protocol (``with ds.solve(p) as sol:``).
"""

from __future__ import annotations

from typing import Any

__all__ = ["Releasable", "destroy_attributes"]


def destroy_attributes(owner: object, names: tuple[str, ...]) -> None:
    """Destroy the PETSc objects in ``owner``'s attributes ``names`` once (collective)."""
    for name in names:
        obj = getattr(owner, name, None)
        if obj is not None:
            obj.destroy()
            setattr(owner, name, None)


class Releasable:
    """``with obj: ...`` calls ``obj.destroy()`` (collective) at the end of the block."""

    def destroy(self) -> None:
        """Release what the object owns (collective; idempotent)."""
        raise NotImplementedError

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.destroy()
