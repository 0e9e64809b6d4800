"""Output of an adaptive run: table rows (CSV, JSON) and fields for ParaView (XDMF).

Every row is written as soon as its level ends, so a run that is interrupted later keeps every
finished level: the CSV is appended and flushed, the JSON is rewritten atomically (temporary file
and rename), and each level's fields go to their own XDMF files, written before its row (a level
in the table has its fields on disk). Rank 0 writes the tables; an error there (a full disk, a
directory removed meanwhile) is raised on every rank (:func:`~dwr_signorini.collective.on_root`),
so the other ranks do not wait for it in the next collective.
"""

from __future__ import annotations

import csv
import json
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

from dolfinx import io

from .collective import on_root

__all__ = ["OutputDirectory", "check_output_dir", "write_csv", "write_json"]


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
    """Write rows (dicts with the same keys) as CSV.

    Args:
        path: The file, overwritten.
        rows: The rows; a dict value (the timings) becomes columns ``key_subkey``.
    """
    flat = [_flatten(r) for r in rows]
    with open(path, "w", newline="") as fh:
        if not flat:
            return
        writer = csv.DictWriter(fh, fieldnames=list(flat[0]))
        writer.writeheader()
        writer.writerows(flat)


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Write JSON atomically: a reader never sees a half-written file.

    Args:
        path: The file, replaced in one step (written beside it first).
        data: What ``json`` writes; NaN and infinities (in dicts and at the top) become null.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        json.dump(_clean(data), fh, indent=1)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def check_output_dir(output_dir: str | os.PathLike, comm: MPI.Comm) -> Path:
    """Check that ``output_dir`` can be created and written, without creating anything.

    Collective: rank 0 checks and broadcasts its verdict.

    Args:
        output_dir: The directory.
        comm: The communicator of the run.

    Returns:
        ``output_dir`` as a path.

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

    Args:
        output_dir: The directory (:func:`check_output_dir`).
        comm: The communicator of the run (collective).
        name: The tables' file name without suffix: ``<name>.csv``, ``<name>.json``.

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
        """Append a finished level's row to the CSV and rewrite the JSON (rank 0).

        Args:
            row: The level's record as a dict (``LevelRecord.as_dict()``).
            meta: Written with the rows into the JSON (the run's settings), if given.

        Both files are complete after every level (the CSV row is flushed to disk, the JSON
        replaced atomically); a run killed between the two writes of a level leaves the JSON
        one level behind the CSV.
        """
        self._create()
        self.rows.append(row)
        on_root(self.comm, f"writing {self.csv_path.name}", self._write_row, row, meta)

    def _write_row(self, row: dict[str, Any], meta: dict[str, Any] | None) -> None:
        flat = _flatten(row)
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
        """Write the fine-mesh fields and the contact-facet fields of one level (XDMF).

        Args:
            level: The level, in the file names ``level_<level>.xdmf`` and
                ``level_<level>_contact.xdmf``.
            fields: Functions on the fine mesh.
            contact_fields: Functions on the contact facets' mesh.
        """
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
