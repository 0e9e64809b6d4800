"""Plot of ``peers.py``'s times against the number of fine cells, from its JSON files.

    scripts/fenicsx python3 benchmarks/plot_peers.py [--results benchmarks/results]
        [--output docs/img/peers_time.png]

Reads ``peers.json`` (1 rank: ours, GetFEM, SNES VI) and, if present, ``peers_np2.json`` (2
ranks: ours, SNES VI). Ours is everything from the macro mesh on (set-up, solve, estimate); the
peers' times are their solves alone.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    """Draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=HERE / "results")
    parser.add_argument("--output", type=Path, default=HERE.parent / "docs/img/peers_time.png")
    args = parser.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    series = (
        ("ours_time", "ours: set-up + solve + estimate", "C0", "o"),
        ("getfem_time", "GetFEM: Model.solve", "C1", "s"),
        ("snes_time", "dolfinx + SNES VI: SNES.solve", "C2", "^"),
    )
    for name, style, suffix in (("peers.json", "-", "1 rank"), ("peers_np2.json", "--", "2 ranks")):
        path = args.results / name
        if not path.exists():
            continue
        rows = json.loads(path.read_text())["rows"]
        cells = [r["num_fine_cells"] for r in rows]
        for key, label, color, marker in series:
            if key in rows[0]:
                ax.loglog(cells, [r[key] for r in rows], style, color=color, marker=marker,
                          label=f"{label}, {suffix}")
    ax.set_xlabel("fine triangles (T_h)")
    ax.set_ylabel("wall-clock time [s]")
    ax.set_title("Example 5.1: ours from the macro mesh on, the peers' solves alone")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output, dpi=120)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
