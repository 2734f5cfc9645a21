"""Figures of docs/plasticity.md, *Warnings before a run*: the shipped cantilever
(cases/cantilever.yaml, 1 x 0.1 x 0.1 m, tip shear load) against Timoshenko's tip
deflection, by element order and by the number of elements across its depth as the
warning counts them (the depth over the median of the tets' mean edge lengths).

    python benchmarks/thin_cantilever.py
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

from fem_frac.app.locking import across
from fem_frac.config.loader import load_case
from fem_frac.mesh.build import build_mesh

CASE = Path(__file__).parent.parent / "cases" / "cantilever.yaml"

if __name__ == "__main__":
    print("| order | element_size | elements across the depth | dofs | tip deflection error |")
    print("|---|---|---|---|---|")
    for order, sizes in ((1, (0.1, 0.05, 0.0333333, 0.025)), (2, (0.1, 0.05))):
        for h in sizes:
            sets = [f"mesh.order={order}", f"mesh.element_size={h}"]
            case, source = load_case(CASE, sets)
            count = across(build_mesh(case.mesh, source.path.parent))[2]
            out = tempfile.mkdtemp()
            subprocess.run([sys.executable, "-m", "fem_frac", "run", str(CASE), "-q", "-o", out,
                            *[a for s in sets for a in ("--set", s)]], check=True,
                           stderr=subprocess.DEVNULL)
            summary = json.loads((Path(out) / "summary.json").read_text())
            print(f"| P{order} | {h:.3g} | {count:.2f} | {summary['counts']['dofs']:,} | "
                  f"{summary['reference']['relative_error']:+.3f} |", flush=True)
