"""An X display for off-screen VTK rendering: the current one, or a private Xvfb server."""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import subprocess
from collections.abc import Iterator

__all__ = ["virtual_display"]


@contextlib.contextmanager
def virtual_display(timeout: float = 20.0) -> Iterator[str | None]:
    """Provide an X display for VTK: the current one, or a private Xvfb started and stopped here.

    Args:
        timeout: Seconds to wait for Xvfb to report its display.

    Yields:
        The display name, e.g. ``":1"``.

    Raises:
        RuntimeError: If no display is set, and Xvfb is missing or does not start.

    Xvfb chooses a free display number itself (``-displayfd``), so concurrent runs do not clash.
    """
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise RuntimeError("no X display and no Xvfb executable for off-screen rendering")
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(
        [xvfb, "-displayfd", str(write_fd), "-screen", "0", "1600x1200x24", "-nolisten", "tcp"],
        pass_fds=(write_fd,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write_fd)
    try:
        ready, _, _ = select.select([read_fd], [], [], timeout)
        number = os.read(read_fd, 64).decode().strip() if ready else ""
        if not number.isdigit():
            raise RuntimeError(f"Xvfb did not start (exit code {proc.poll()})")
        os.environ["DISPLAY"] = f":{number}"
        yield os.environ["DISPLAY"]
    finally:
        os.close(read_fd)
        os.environ.pop("DISPLAY", None)
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
