"""What a run reports per level or load step: its table row, progress line, tables and callback.

:class:`LevelRecord` is one row of a run's table and :class:`AdaptiveResult` the run's rows with
its last solution and estimate. :class:`Reporter` reports every finished level of
:func:`~dwr_signorini.solve_adaptive` and every load step of :func:`~dwr_signorini.solve_path`
the same way: the fields and the table row to the output directory (:mod:`dwr_signorini.io`),
the progress line through :mod:`logging` (the logger ``dwr_signorini.report``, on rank 0), and
the user's callback on every rank.

The progress lines are INFO records. With ``verbose=True`` a run shows them on standard output
(rank 0), as lines of the bare message, and keeps them from the handlers of the loggers above
while it runs; with ``verbose=False`` they reach only the handlers that the application
configured (``logging.basicConfig(level=logging.INFO)`` shows them on standard error).
"""

from __future__ import annotations

import logging
import math
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

from .collective import call_collectively, on_root
from .estimator import Estimate
from .io import OutputDirectory, write_csv, write_json
from .lifetime import Releasable
from .model_error import law_phrase
from .model_regions import model_label
from .newton import Solution
from .problem import SignoriniProblem
from .stress import stress_fields
from .timing import timed

__all__ = ["AdaptiveResult", "LevelRecord", "Reporter", "level_record", "progress_line"]

logger = logging.getLogger(__name__)


@dataclass
class LevelRecord:
    """One row of the table of an adaptive or uniform run (the paper's Tables 1-3).

    Attributes:
        level: The level, from 0.
        num_cells: M_Omega, cells of T_h.
        num_macro_cells: Cells of T_H.
        num_contact_elements: M_C, macro contact facets (multipliers).
        num_dofs: Displacement DoFs.
        num_active: Active multipliers at convergence (0: no facet is in contact, see
            ``no_contact``).
        J_h: J(w_h).
        eta_p: The primal estimator.
        eta: The primal-dual estimator, or ``None`` when only eta_p was asked for.
        estimate: The estimator that drove the run (eta or eta_p).
        contact_term: C(w_h)(xi_H).
        active_set_remainder: R_A (:attr:`Estimate.active_set_remainder`).
        newton_iterations: Newton steps of this level.
        num_marked: Macro cells marked on this level for the next (over all ranks).
        time: Seconds per phase (``solve``, ``dual``, ``estimate``, ``refine``, ..., ``total``).
        rel_error: E_rel against the ``exact`` of :func:`solve_adaptive`, else ``None``.
        ieff_p: Ieff of eta_p against ``exact``, else ``None``.
        ieff: Ieff of eta against ``exact``, else ``None``.
        J_low: The lower end of the interval for J(w) (:attr:`Estimate.interval`, under the
            assumptions of :mod:`~dwr_signorini.interval`).
        J_high: Its upper end.
        J_best: The best estimate of J(w), the centre of [J_low, J_high]: J_h corrected by the
            estimate (:attr:`Estimate.J_best`). J_h itself is often outside the interval.
        no_contact: Whether no facet is in contact on this level (``num_active == 0``).
        weights_fallback: Why ``weights="auto"`` kept the patch weights where P2 ones did not
            fit in memory (:attr:`Estimate.weights_fallback`), else ``None``.
        weights: The weights the level's estimate used ("patch", "hierarchical", ...).
        resolved: Whether the level's contact set counted as resolved.
        num_stick: With friction, macro contact facets in contact that stick, else None.
        num_slip: With friction, macro contact facets in contact that slip, else None.
        method: The linear solver of the level's Newton steps (:attr:`Solution.method`:
            ``"block"``, ``"schur"`` or ``"krylov"``).
        model_error: With ``solve_adaptive(..., model_error=richer)``: the estimate of
            J(richer) - J(simpler) (:attr:`Estimate.model_error`), else ``None``.
        model_error_low: The lower end of its interval, else ``None``.
        model_error_high: Its upper end, else ``None``.
        model: The name of the contact law the level ran (``"frictionless"``, ``"tresca"``,
            ``"coulomb"``); with ``solve_adaptive(..., models=[...])`` the model it chose.
        richer_model: The name of the richer law of ``model_error`` (``"finite_strain"`` for a
            hyperelastic material), else ``None``.
        rich_share: With ``models``: the share of Gamma_C (by measure) that ran the richest
            law (0 or 1 for a global switch; per region R's), else ``None``.
    """

    level: int
    num_cells: int
    num_macro_cells: int
    num_contact_elements: int
    num_dofs: int
    num_active: int
    J_h: float
    eta_p: float
    eta: float | None
    estimate: float
    contact_term: float
    active_set_remainder: float
    newton_iterations: int
    num_marked: int = 0
    time: dict[str, float] = field(default_factory=dict)
    rel_error: float | None = None
    ieff_p: float | None = None
    ieff: float | None = None
    J_low: float | None = None
    J_high: float | None = None
    J_best: float | None = None
    no_contact: bool = False
    weights_fallback: str | None = None
    weights: str = ""
    resolved: bool = True
    num_stick: int | None = None
    num_slip: int | None = None
    method: str = ""
    model_error: float | None = None
    model_error_low: float | None = None
    model_error_high: float | None = None
    model: str = ""
    richer_model: str | None = None
    rich_share: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The record as a plain dict.

        Returns:
            The fields by name, the timings nested under ``time``.
        """
        return asdict(self)


@dataclass
class AdaptiveResult(Releasable):
    """The levels of a run and the last solution and estimate.

    Owns the last level's solution and estimate: release them with :meth:`destroy`
    (collective), or use the result as a context manager.

    Attributes:
        levels: One :class:`LevelRecord` per level.
        solution: The last level's :class:`~dwr_signorini.Solution`.
        estimate: The last level's :class:`~dwr_signorini.Estimate`.
        problem: The problem on the last level's macro mesh.
        meta: The run's settings (written by :meth:`to_json`).
        comm: The mesh communicator.
        converged: Whether the run stopped on ``tol``: J_high - J_low <= 2 tol on the last
            level. False when it ended at ``max_levels`` or ``max_cells`` without that, and
            always without ``tol``.
        stopped_by: Why the run stopped: ``"tol"`` (converged), ``"max_levels"`` or
            ``"max_cells"``; one line on rank 0 says so (:class:`Reporter`).
        next_cells: The fine cells of the level after the last one refined (what
            ``max_cells`` was compared with).
        model_map: With ``model_regions``: per level which macro contact facets ran Coulomb
            (:meth:`~dwr_signorini.model_regions.RegionMap.as_dict`), else empty.
    """

    levels: list[LevelRecord]
    solution: Solution | None = field(default=None, repr=False)
    estimate: Estimate | None = field(default=None, repr=False)
    problem: SignoriniProblem | None = field(default=None, repr=False)
    meta: dict[str, Any] = field(default_factory=dict)
    comm: MPI.Comm = field(default_factory=lambda: MPI.COMM_WORLD, repr=False)
    converged: bool = False
    stopped_by: str = ""
    next_cells: int = 0
    model_map: list[dict[str, Any]] = field(default_factory=list, repr=False)

    def destroy(self) -> None:
        """Release the last level's solution and estimate (collective; idempotent)."""
        if self.solution is not None:
            self.solution.destroy()
        if self.estimate is not None:
            self.estimate.destroy()


    def rows(self) -> list[dict[str, Any]]:
        """The table as a list of dicts.

        Returns:
            One :meth:`LevelRecord.as_dict` per level.
        """
        return [r.as_dict() for r in self.levels]

    def to_csv(self, path: str | Path) -> None:
        """Write the table as CSV (rank 0 of the mesh communicator writes; collective).

        Args:
            path: The CSV file, in an existing directory.
        """
        on_root(self.comm, f"to_csv({str(path)!r})", write_csv, path, self.rows())

    def to_json(self, path: str | Path) -> None:
        """Write the table and the run's settings as JSON (rank 0 writes; collective).

        Args:
            path: The JSON file, in an existing directory (written atomically).
        """
        data = {"meta": self.meta, "levels": self.rows()}
        on_root(self.comm, f"to_json({str(path)!r})", write_json, path, data)


def level_record(
    level: int,
    disc: Any,
    sol: Solution,
    est: Estimate,
    marked: np.ndarray,
    times: dict[str, float],
    exact: float | None,
) -> LevelRecord:
    """The table row of a finished level or load step.

    Args:
        level: The refinement level.
        disc: The level's discretisation.
        sol: Its solution.
        est: Its estimate.
        marked: The macro cells marked on this rank for the next level.
        times: Seconds of the phases ``setup``, ``solve`` and ``refine``.
        exact: The exact J, if known (fills rel_error and the effectivity indices).

    Returns:
        The :class:`LevelRecord`, without the ``total`` time.
    """
    sizes = ("num_cells", "num_macro_cells", "num_contact_elements", "num_dofs")
    values = ("J_h", "J_best", "eta_p", "eta", "contact_term", "active_set_remainder",
              "weights", "weights_fallback", "resolved")
    J_low, J_high = est.interval
    model_low, model_high = est.model_error_interval or (None, None)
    record = LevelRecord(
        level=level,
        **{name: getattr(disc, name) for name in sizes},
        **{name: getattr(est, name) for name in values},
        estimate=est.value,
        J_low=J_low,
        J_high=J_high,
        num_active=sol.num_active,
        no_contact=sol.num_active == 0,
        num_stick=sol.num_stick,
        num_slip=sol.num_slip,
        method=sol.method,
        model_error=est.model_error,
        model_error_low=model_low,
        model_error_high=model_high,
        model=model_label(disc.problem),
        richer_model=None if est.model is None else est.model.richer,
        newton_iterations=sol.newton_iterations,
        num_marked=disc.comm.allreduce(len(marked), op=MPI.SUM),
        time={
            "setup": times["setup"],
            "solve": times["solve"],
            "dual": est.timings["dual"],
            "estimate": est.timings["estimate"],
            "refine": times["refine"],
        },
    )
    if exact is not None:
        err = exact - est.J_h
        record.rel_error = abs(err) / abs(exact) if exact != 0 else abs(err)
        record.ieff_p = err / est.eta_p if est.eta_p != 0 else math.inf
        if est.eta is not None:
            record.ieff = err / est.eta if est.eta != 0 else math.inf
    return record



def progress_line(record: LevelRecord, label: str | None = None) -> str:
    """The progress line of a level (or of a load step, ``label``).

    Args:
        record: The level's row.
        label: What the line starts with (default: ``level <level>``).

    Returns:
        The line, without a newline.
    """
    friction = (
        "" if record.num_stick is None
        else f"stick/slip {record.num_stick:d}/{record.num_slip:d}  "
    )
    contact = "no contact  " if record.no_contact else ""
    if record.model_error is None and record.num_stick is not None:
        contact += f"model {record.model}  "
    if record.model_error is not None:
        phrase = law_phrase(record.model, record.richer_model)
        contact += (
            f"model {record.model}; model error of {phrase}: {record.model_error: .3e} in "
            f"[{record.model_error_low: .3e}, {record.model_error_high: .3e}]  "
        )
    if record.rich_share is not None:
        contact += f"rich law on {record.rich_share:.0%} of Gamma_C  "
    fallback = ", memory" if record.weights_fallback else ""
    label = f"level {record.level:2d}" if label is None else label
    return (
        f"{label}  cells {record.num_cells:8d}  dofs {record.num_dofs:8d}  "
        f"J_best {record.J_best: .6e}  J in [{record.J_low: .6e}, {record.J_high: .6e}]  "
        f"J_h {record.J_h: .6e}  "
        f"estimate {record.estimate: .3e} ({record.weights}{fallback})  {contact}{friction}"
        f"newton {record.newton_iterations:2d} ({record.method})  "
        f"{record.time['total']:7.2f} s"
    )


@contextmanager
def _on_stdout(show: bool) -> Iterator[None]:
    """While open, the records of this module's logger go to standard output (if ``show``)."""
    if not show:
        yield
        return
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(logging.Formatter("%(message)s"))
    level, propagate = logger.level, logger.propagate
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
        logger.propagate = propagate


class Reporter:
    """Reports the finished levels or load steps of one run (module docstring).

    Use it as a context manager around the run's loop: while open, ``verbose`` shows the
    progress lines on standard output.

    Args:
        comm: The run's communicator (collective).
        name: The tables' file name without suffix (``<name>.csv``, ``<name>.json``).
        meta: The run's settings, written with the rows into the JSON.
        output_dir: Where to write the tables (after every level) and fields (XDMF), or None.
        callback: Called as ``callback(record, solution, estimate)`` after every level, on
            every rank; an exception it raises on any rank is raised on every rank
            (:mod:`dwr_signorini.collective`).
        verbose: Show a progress line per level on rank 0.
        series: Write the fields as one time series (a load path,
            :meth:`~dwr_signorini.io.OutputDirectory.write_fields`), not one file per level.

    Raises:
        TypeError: A ``callback``, ``verbose`` or ``output_dir`` of the wrong type.
        ValueError: An ``output_dir`` that cannot be written
            (:func:`~dwr_signorini.io.check_output_dir`).
    """

    def __init__(
        self,
        comm: MPI.Comm,
        name: str,
        meta: dict[str, Any],
        output_dir: str | os.PathLike | None = None,
        callback: Callable[..., None] | None = None,
        verbose: bool = True,
        series: bool = False,
    ) -> None:
        if callback is not None and not callable(callback):
            raise TypeError(f"callback must be callable or None, got {callback!r}")
        if not isinstance(verbose, bool):
            raise TypeError(f"verbose must be True or False, got {verbose!r}")
        if output_dir is not None and not isinstance(output_dir, (str, os.PathLike)):
            raise TypeError(
                f"output_dir must be a path (str or pathlib.Path) or None, got {output_dir!r}"
            )
        self.comm, self.meta, self.callback, self.verbose = comm, meta, callback, verbose
        self.series = series
        self.out = None if output_dir is None else OutputDirectory(output_dir, comm, name=name)
        self._stdout = _on_stdout(verbose and comm.rank == 0)

    def __enter__(self) -> Reporter:
        self._stdout.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.out is not None:
            self.out.close()
        self._stdout.__exit__(*exc)

    def report(
        self,
        index: int,
        record: LevelRecord,
        sol: Solution,
        est: Estimate,
        label: str | None = None,
    ) -> None:
        """Report a finished level: fields and row, progress line, callback (collective).

        Args:
            index: The level (or load step) in the fields' file names.
            record: Its row.
            sol: Its solution.
            est: Its estimate.
            label: The start of the progress line (default: ``level <level>``).
        """
        if self.out is not None:
            with timed("output"):  # the fields first: a level in the table has its fields
                # no stress fields at finite strain (P(F), not Hooke's law; :func:`stress_fields`)
                stresses = () if sol.disc.problem.finite_strain else stress_fields(sol)
                fields = [sol.u, est.indicators, est.dual.y, *stresses]
                self.out.write_fields(index, fields, [*sol.multipliers, *est.dual.multipliers],
                                      series=self.series)
                self.out.append(record.as_dict(), self.meta)
        self.say(progress_line(record, label))
        if self.callback is not None:
            call_collectively(self.comm, "callback", self.callback, record, sol, est)

    def say(self, line: str) -> None:
        """Log ``line`` on rank 0 (INFO; on standard output with ``verbose``).

        Args:
            line: The message.
        """
        if self.comm.rank == 0:
            logger.info(line)
