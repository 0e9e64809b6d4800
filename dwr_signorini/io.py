"""Output of an adaptive run: table rows (CSV, JSON) and fields for ParaView (XDMF, VTX).

Every row is written as soon as its level ends, so a run that is interrupted later keeps every
finished level: the CSV is appended and flushed, the JSON is rewritten atomically (temporary file
and rename), and each level's fields are written before its row (a level in the table has its
fields on disk): an adaptive run's levels to their own XDMF files, a load path's steps to one
time series (Time = the step; a step on a refined mesh adds its mesh to the file). Where dolfinx
has ADIOS2 the same fields also go to VTX files (``.bp``). Rank 0 writes the tables; an error
there (a full disk, a directory removed meanwhile) is raised on every rank
(:func:`~dwr_signorini.collective.on_root`), so the other ranks do not wait for it in the next
collective.
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

from dolfinx import fem, io

from . import compat
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
        #: The mesh last written to each XDMF file (by stem) and its name there.
        self._meshes: dict[str, tuple[Any, str]] = {}
        self._vtx = _VTXFiles(self.path, comm) if compat.has_vtx() else None

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
        self,
        level: int,
        fields: Sequence[Any],
        contact_fields: Sequence[Any],
        series: bool = False,
    ) -> None:
        """Write the fine-mesh fields and the contact-facet fields of one level (XDMF, VTX).

        Args:
            level: The level (or load step).
            fields: Functions on the fine mesh.
            contact_fields: Functions on the contact facets' mesh.
            series: Append to one time series, ``<name>.xdmf`` and ``<name>_contact.xdmf``
                at Time = ``level`` (a load path); a mesh that differs from the last one
                written there is added to the file. Otherwise (the levels of an adaptive run,
                each on its own mesh) ``level_<level>.xdmf`` and ``level_<level>_contact.xdmf``,
                at Time = ``level`` as well.

        Where dolfinx has ADIOS2 (:func:`~dwr_signorini.compat.has_vtx`) the same fields go to
        VTX files (``.bp``, for ParaView's ADIOS2 reader), one per mesh and element (P1, DG0).
        """
        self._create()
        for suffix, funcs in (("", fields), ("_contact", contact_fields)):
            if not funcs:
                continue
            stem = f"{self.name}{suffix}" if series else f"level_{level:02d}{suffix}"
            self._write_xdmf(stem, level, funcs)
            if self._vtx is not None:
                self._vtx.write(stem, level, funcs)
        if self._vtx is not None and not series:  # a level's files are complete
            self._vtx.close()

    def _write_xdmf(self, stem: str, level: int, funcs: Sequence[Any]) -> None:
        """Write ``funcs`` at Time = ``level`` to ``<stem>.xdmf``, its mesh once (collective)."""
        msh = funcs[0].function_space.mesh
        key = getattr(msh, "_cpp_object", msh)
        path = self.path / f"{stem}.xdmf"
        known = self._meshes.get(stem)
        new_file = known is None
        new_mesh = new_file or known[0] is not key
        # the first mesh of a file under its own name (read_mesh() finds it), later ones
        # (a refined mesh in a time series) under <name>_<level>
        name = msh.name if new_file else f"{msh.name}_{level}" if new_mesh else known[1]
        with io.XDMFFile(self.comm, path, "w" if new_file else "a") as xdmf:
            if new_mesh:
                old, msh.name = msh.name, name
                try:
                    xdmf.write_mesh(msh)
                finally:
                    msh.name = old
                self._meshes[stem] = (key, name)
            xpath = f"/Xdmf/Domain/Grid[@Name='{name}'][1]"
            for f in funcs:
                xdmf.write_function(f, float(level), mesh_xpath=xpath)

    def close(self) -> None:
        """Close the open VTX files (collective; idempotent)."""
        if self._vtx is not None:
            self._vtx.close()
        self._meshes.clear()


class _VTXFiles:
    """VTX (ADIOS2) files of the fields: one writer per stem, mesh and element, kept open.

    A writer is bound to the functions it was made with, so it holds copies that each call
    refreshes while the mesh stays; a new mesh closes it and starts the next file,
    ``<stem>_<element>.bp`` for the first mesh, ``<stem>_<element>_<level>.bp`` after.
    """

    def __init__(self, path: Path, comm: MPI.Comm) -> None:
        self.path, self.comm = path, comm
        self.writers: dict[tuple[str, str], tuple[Any, Any, list[Any]]] = {}

    def write(self, stem: str, level: int, funcs: Sequence[Any]) -> None:
        groups: dict[str, list[Any]] = {}
        for f in funcs:
            element = f.function_space.ufl_element()
            kind = f"{'dg' if element.discontinuous else 'p'}{element.embedded_superdegree}"
            groups.setdefault(kind, []).append(f)
        for kind, group in groups.items():
            self._write_group(stem, kind, level, group)

    def _write_group(self, stem: str, kind: str, level: int, group: list[Any]) -> None:
        msh = group[0].function_space.mesh
        key = getattr(msh, "_cpp_object", msh)
        entry = self.writers.get((stem, kind))
        fits = entry is not None and entry[0] is key and [c.name for c in entry[2]] == [
            f.name for f in group
        ] and all(c.x.array.size == f.x.array.size for c, f in zip(entry[2], group, strict=True))
        if not fits:
            suffix = "" if entry is None else f"_{level:02d}"
            if entry is not None:
                entry[1].close()
            copies = [fem.Function(f.function_space, name=f.name) for f in group]
            writer = io.VTXWriter(self.comm, self.path / f"{stem}_{kind}{suffix}.bp", copies,
                                  engine="BP4")
            entry = self.writers[(stem, kind)] = (key, writer, copies)
        for copy, f in zip(entry[2], group, strict=True):
            copy.x.array[:] = f.x.array
        entry[1].write(float(level))

    def close(self) -> None:
        for _, writer, _ in self.writers.values():
            writer.close()
        self.writers.clear()
