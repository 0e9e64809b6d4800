"""Errors that reach every rank: user code and one-rank failures evaluated collectively.

Under MPI an exception raised on one rank only leaves the others waiting in the next collective
(an assembly, a reduction, a barrier) for ever. The package's own checks of data reduce their
verdict over the communicator before they raise; this module does the same for code whose
failure it cannot foresee:

* **user code**: the goal, the callables for ``E``, ``nu``, ``gap`` (and a
  :class:`~dwr_signorini.obstacles.Graph`'s ``psi``), prescribed values, body force and
  tractions, the boundary projections, the ``callback`` of
  :func:`~dwr_signorini.solve_adaptive`;
* **one-rank failures of the package**: a file that rank 0 alone writes (the tables of an
  adaptive run, :mod:`dwr_signorini.io`), a mesh file that one rank reads
  (:func:`~dwr_signorini.read_mesh`), a linear solve that raises on one rank first.

Each such call runs through :func:`call_collectively` (or the block form :func:`collective`):
every rank runs its part, then all ranks exchange whether it raised (one ``allgather``). If any
rank raised, every rank raises the *same* exception: a :class:`CollectiveError` whose message
names where the error came from, the rank(s) it was raised on, the original type and message,
e.g.::

    goal raised ValueError on rank 1 of 2: a goal that fails on one rank

The exception is also an instance of the original type when that is possible (a
``ValueError`` becomes a ``CollectiveValueError``, a subclass of both ``CollectiveError`` and
``ValueError``), so ``except ValueError`` still catches it; on the rank that raised, the
original exception is its ``__cause__``.

Rules for a guarded region (why the regions are small): it must contain no collective operation
(no assembly, no JIT compilation, no reduction), since a rank that failed early would leave the
others inside it; and every rank of the communicator must reach it, in the same order. A guard
inside a guard (the user's ``E`` called through ``m.sigma(u)`` inside the goal) does not
communicate: only the outermost guard agrees, so that a rank that fails before it reaches the
inner guard cannot pair that guard's exchange with the outer one of another rank.
``KeyboardInterrupt`` and other ``BaseException`` classes that are not ``Exception`` classes are
not intercepted: a signal reaches every rank of an ``mpirun`` anyway.

The exchanges of Python objects (``allgather``, ``allreduce``, ``bcast`` in lower case) run on
:func:`shadow` of a communicator, never on a mesh's own. mpi4py 4.0 caches a lock table and a
duplicate as attributes of every communicator such an exchange ran on, and frees them in
``MPI_Comm_free``'s delete callback; the communicator of a dolfinx mesh is freed by the C++
destructor of the mesh, so when the last reference to a mesh goes while an exception propagates
(``ds.solve_path([make(d) for d in loads])`` with the goal forgotten), mpi4py 4.0.3's callback
runs with that exception set, fails ("SystemError ... commlock_free_cb"), keeps its lock and the
next free waits for it for ever.

Messages about a collective state (a Newton step's global residuals, a safeguard all ranks take)
are logged once, on rank 0 (:func:`log_on_root`), not once per rank.
"""

from __future__ import annotations

import functools
import logging
import pickle
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from mpi4py import MPI

__all__ = ["CollectiveError", "agree", "call_collectively", "collective", "log_on_root", "on_root",
           "shadow"]

T = TypeVar("T")

#: How many guards the running code is inside of: only the outermost one communicates.
_depth = 0

#: One duplicate per group of processes (their ranks in COMM_WORLD), for the life of the process.
_shadows: dict[tuple[int, ...], MPI.Intracomm] = {}


def shadow(comm: MPI.Intracomm) -> MPI.Intracomm:
    """A duplicate of ``comm`` that lives as long as the process, for exchanges of objects.

    Lower-case collectives (``allgather``, ``allreduce``, ``bcast``) of mpi4py 4.0 leave
    attributes on the communicator they run on, and a mesh's communicator must not carry any:
    dolfinx frees it whenever the mesh goes, possibly while an exception propagates, and then
    mpi4py's delete callback hangs (module docstring). Communicators of the same processes share
    one duplicate; it is never freed before the end of the process. COMM_WORLD and COMM_SELF
    are returned as they are (they are never freed), and so is a communicator with processes
    outside COMM_WORLD (spawned ones).

    Collective on ``comm`` the first time for its processes (``Dup``), local afterwards.

    Args:
        comm: An intracommunicator, e.g. ``mesh.comm``.

    Returns:
        The communicator to run object collectives on, congruent with ``comm``.
    """
    if comm == MPI.COMM_WORLD or comm == MPI.COMM_SELF:
        return comm
    group, world = comm.Get_group(), MPI.COMM_WORLD.Get_group()
    try:
        key = tuple(int(r) for r in MPI.Group.Translate_ranks(group, None, world))
    finally:
        group.Free()
        world.Free()
    if MPI.UNDEFINED in key:  # processes outside COMM_WORLD (spawned): nothing to key on
        return comm
    if key not in _shadows:
        _shadows[key] = comm.Dup()
    return _shadows[key]


class CollectiveError(Exception):
    """An exception raised on some ranks, raised the same on every rank of a communicator.

    Attributes:
        where: What raised it (``"goal"``, ``"E"``, ``"boundary_projection[3]"``, ...).
        ranks: The ranks on which it was raised.
        error_type: The name of the type of the original exception (of the lowest such rank).
        error_message: Its message.
    """

    where: str = ""
    ranks: tuple[int, ...] = ()
    error_type: str = ""
    error_message: str = ""

    def __str__(self) -> str:
        # The text, also where the original type formats its own fields (PETSc.Error's ierr).
        return str(self.args[0]) if self.args else ""


@functools.cache
def _collective_class(base: type[BaseException]) -> type[CollectiveError]:
    """``CollectiveError`` mixed with ``base`` (the original type), or plain if impossible."""
    if issubclass(base, CollectiveError) or not issubclass(base, Exception):
        return CollectiveError
    try:
        return type(f"Collective{base.__name__}", (CollectiveError, base), {"__module__": __name__})
    except TypeError:  # a base that cannot be mixed (layout conflict, final class)
        return CollectiveError


def _build(
    where: str, failures: list[tuple[int, bytes | None, str, str]], size: int
) -> CollectiveError:
    """The exception for ``failures`` (rank, pickled type, type name, message), on every rank."""
    rank, blob, type_name, message = failures[0]
    ranks = tuple(f[0] for f in failures)
    where_ranks = f"rank {rank}" if len(ranks) == 1 else "ranks " + ", ".join(map(str, ranks))
    on = f" on {where_ranks} of {size}" if size > 1 else ""
    text = f"{where} raised {type_name}{on}: {message}"
    cls = _collective_class(_load_type(blob))
    try:
        # Bypass custom __init__s (e.g. ConvergenceError's history): the message is the text.
        exc = cls.__new__(cls, text)
        Exception.__init__(exc, text)
    except TypeError:
        exc = CollectiveError(text)
    exc.where, exc.ranks = where, ranks
    exc.error_type, exc.error_message = type_name, message
    return exc


def agree(comm: MPI.Comm, where: str, error: Exception | None) -> None:
    """Raise the same :class:`CollectiveError` on every rank if ``error`` is set on any.

    Collective. If every rank has the same :class:`CollectiveError` (that of a nested guard on
    the same communicator), it is raised again unchanged.

    Args:
        comm: The communicator whose ranks must agree.
        where: What the error came from, for the message.
        error: This rank's exception, or ``None``.
    """
    local = None if error is None else _describe(error)
    gathered = [local] if comm.size == 1 else shadow(comm).allgather(local)
    if isinstance(error, CollectiveError) and all(g == local for g in gathered):
        raise error
    failures = [(r, *g) for r, g in enumerate(gathered) if g is not None]
    if failures:
        raise _build(where, failures, comm.size) from error


def _describe(error: Exception) -> tuple[bytes | None, str, str]:
    """The type (pickled, if it can be), its name and the message of ``error``.

    Plain bytes and strings: sending them cannot fail (the type itself may not pickle).
    """
    try:
        blob: bytes | None = pickle.dumps(type(error))
    except Exception:  # a local class, say: it arrives as RuntimeError
        blob = None
    try:
        message = str(error)
    except Exception:
        message = object.__repr__(error)
    return blob, type(error).__name__, message


def _load_type(blob: bytes | None) -> type[BaseException]:
    try:
        loaded = pickle.loads(blob) if blob is not None else RuntimeError
    except Exception:
        return RuntimeError
    return loaded if isinstance(loaded, type) and issubclass(loaded, Exception) else RuntimeError


def call_collectively(
    comm: MPI.Comm, where: str, function: Callable[..., T], *args: Any, **kwargs: Any
) -> T:
    """``function(*args, **kwargs)`` on every rank; an exception on any rank raises on all.

    Collective (one ``allgather``). ``function`` must not communicate (module docstring).

    Args:
        comm: The communicator.
        where: What is called, named in the error (e.g. ``"goal"``, ``"nu"``).
        function: The (user's) callable.
        args: Its positional arguments.
        kwargs: Its keyword arguments.

    Returns:
        What ``function`` returned on this rank.

    Raises:
        CollectiveError: On every rank, if ``function`` raised on any.
    """
    result: Any = None
    with collective(comm, where):
        result = function(*args, **kwargs)
    return result


@contextmanager
def collective(comm: MPI.Comm, where: str) -> Iterator[None]:
    """Guard a block of local code: an exception in it on any rank raises on every rank.

    Collective at the end of the block (one ``allgather``); the block must not communicate.

    Args:
        comm: The communicator.
        where: What the block does, named in the error.

    Raises:
        CollectiveError: On every rank, if the block raised on any.
    """
    global _depth
    if _depth > 0:  # inside another guard: that one agrees
        yield
        return
    error: Exception | None = None
    _depth += 1
    try:
        yield
    except Exception as err:
        error = err
    finally:
        _depth -= 1
    agree(comm, where, error)


def on_root(
    comm: MPI.Comm, where: str, function: Callable[..., T], *args: Any, root: int = 0
) -> T | None:
    """``function(*args)`` on rank ``root`` only (e.g. writing a file); its error on every rank.

    Returns:
        What ``function`` returned on ``root``, ``None`` on the other ranks.

    Raises:
        CollectiveError: On every rank, if ``function`` raised on ``root``.
    """
    with collective(comm, where):
        if comm.rank == root:
            return function(*args)
    return None


def log_on_root(comm: MPI.Comm, logger: logging.Logger, level: int, msg: str, *args: Any) -> None:
    """``logger.log(level, msg, *args)`` on rank 0 only: a message about a state all ranks share."""
    if comm.rank == 0:
        logger.log(level, msg, *args)
