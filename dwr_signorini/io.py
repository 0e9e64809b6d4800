"""Output of an adaptive run: table rows (CSV, JSON) and fields for ParaView (XDMF).

Every row is written as soon as its level ends, so a run that is interrupted later keeps every
finished level: the CSV is appended and flushed, the JSON is rewritten atomically (temporary file
and rename), and each level's fields go to their own XDMF files, written before its row (a level
in the table has its fields on disk). Rank 0 writes the tables; an error there (a full disk, a
directory removed meanwhile) is raised on every rank (:func:`~dwr_signorini.collective.on_root`),
so the other ranks do not wait for it in the next collective.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import signal
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

from dolfinx import io

from .collective import on_root

__all__ = ["OutputDirectory", "check_output_dir", "signals_deferred", "write_csv", "write_json"]


def _clean(value: Any) -> Any:
    """JSON-safe value (NaN/Inf become None)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    return value


def _flatten(row: dict[str, Any]) -> dict[str, Any]:
    """Nested dicts (the timings) become ``time_<phase>`` columns."""
    flat: dict[str, Any] = {}
    for key, value in row.items():
        if isinstance(value, dict):
            for sub, v in value.items():
                flat[f"{key}_{sub}"] = v
        else:
            flat[key] = value
    return flat


def write_csv(path: str | os.PathLike, rows: Sequence[dict[str, Any]]) -> None:
    """Write rows (dicts with the same keys) as CSV."""
    flat = [_flatten(r) for r in rows]
    with open(path, "w", newline="") as fh:
        if not flat:
            return
        writer = csv.DictWriter(fh, fieldnames=list(flat[0]))
        writer.writeheader()
        writer.writerows(flat)


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the block; they are delivered when it ends.

    Their handlers are replaced by one that only records them, and the recorded signals are
    raised again with the former handlers once the block is left (a default SIGTERM then ends
    the process, SIGINT raises KeyboardInterrupt). Masking the signals would not do: in a
    process with other threads (MPI's) the kernel hands them to a thread that does not mask
    them. On a thread other than the main one the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def record(signum: int, frame: Any) -> None:
        received.append(signum)

    held = (signal.SIGINT, signal.SIGTERM)
    former = {s: signal.signal(s, record) for s in held}
    try:
        yield
    finally:
        for s, handler in former.items():  # None: a handler not set from Python
            signal.signal(s, signal.SIG_DFL if handler is None else handler)
        for s in dict.fromkeys(received):
            signal.raise_signal(s)


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Write JSON atomically: a reader never sees a half-written file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(_clean(data), fh, indent=1)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def check_output_dir(output_dir: str | os.PathLike, comm: MPI.Comm) -> Path:
    """Check that ``output_dir`` can be created and written, without creating anything.

    Raises:
        ValueError: If the path is a file, or its nearest existing ancestor is not writable.
    """
    path = Path(output_dir)
    error = None
    if comm.rank == 0:
        if path.exists() and not path.is_dir():
            error = f"output_dir {str(path)!r} exists and is not a directory"
        else:
            probe = path
            while not probe.exists():
                probe = probe.parent
            if not os.access(probe, os.W_OK | os.X_OK):
                error = f"output_dir {str(path)!r} is not writable (no write access to {probe})"
    error = comm.bcast(error, root=0)
    if error:
        raise ValueError(error)
    return path


class OutputDirectory:
    """Writes the table rows and fields of each level of an adaptive run.

    The directory is checked at once but created only when the first level is written, so a
    run that fails before finishing a level leaves nothing behind.
    """

    def __init__(self, output_dir: str | os.PathLike, comm: MPI.Comm, name: str = "adaptive"):
        self.path = check_output_dir(output_dir, comm)
        self.comm = comm
        self.name = name
        self.rows: list[dict[str, Any]] = []
        self._created = False

    def _create(self) -> None:
        if self._created:
            return
        on_root(self.comm, f"output_dir {str(self.path)!r}", self._make)
        self._created = True

    def _make(self) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        self.csv_path.unlink(missing_ok=True)

    @property
    def csv_path(self) -> Path:
        """The CSV table."""
        return self.path / f"{self.name}.csv"

    @property
    def json_path(self) -> Path:
        """The JSON table."""
        return self.path / f"{self.name}.json"

    def append(self, row: dict[str, Any], meta: dict[str, Any] | None = None) -> None:
        """Append a finished level's row to the CSV and rewrite the JSON (rank 0)."""
        self._create()
        self.rows.append(row)
        on_root(self.comm, f"writing {self.csv_path.name}", self._write_row, row, meta)

    def _write_row(self, row: dict[str, Any], meta: dict[str, Any] | None) -> None:
        """The row into the CSV and the JSON, with SIGINT and SIGTERM held until both are written.

        An interrupted run so leaves the two tables with the same levels.
        """
        flat = _flatten(row)
        with signals_deferred():
            new = not self.csv_path.exists()
            with open(self.csv_path, "a", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=list(flat))
                if new:
                    writer.writeheader()
                writer.writerow(flat)
                fh.flush()
                os.fsync(fh.fileno())
            write_json(self.json_path, {"meta": meta or {}, "levels": self.rows})

    def write_fields(
        self, level: int, fields: Sequence[Any], contact_fields: Sequence[Any]
    ) -> None:
        """Write the fine-mesh fields and the contact-facet fields of one level (XDMF)."""
        self._create()
        for suffix, funcs in (("", fields), ("_contact", contact_fields)):
            if not funcs:
                continue
            msh = funcs[0].function_space.mesh
            path = self.path / f"level_{level:02d}{suffix}.xdmf"
            with io.XDMFFile(self.comm, path, "w") as xdmf:
                xdmf.write_mesh(msh)
                for f in funcs:
                    xdmf.write_function(f)
