#!/usr/bin/env python3
"""Overlay σ1/σ3 against the shearing stage's axial strain for several mufe runs of one
cell (a rate or mesh study: the same stage 1, stage 2 at different settings), with an
optional theory line; prints each run's sampled peak and where it is, and the first row at
which a grain pair in contact at the stage's start has opened (the paper's "failure": a
gap opens between initially touching spheres), marked on the curve.

How to run:  scripts/plot_stress_ratio.py DIR[=LABEL] DIR[=LABEL] ... --out FILE.png
                 [--stage 2] [--theory 3.128 --theory-label "Thornton, μ = 0.22"]
Needs h5py and matplotlib (apt install python3-h5py python3-matplotlib). Each DIR holds
a results.h5; the axial strain is strain_z from the last history row before the stage. A
run branched at the stage (`--restart … --branch`) has no such row: it takes the first
listed run's, which is right when both continue the same stage-1 checkpoint.
"""
import argparse

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def stage_rows(path, stage):
    """(strain_z before the stage or None, strain_z, σ1/σ3 and grain pairs in contact of
    the rows in `stage`)."""
    with h5py.File(f"{path}/results.h5", "r") as f:
        h = f["history"]
        st = h["stage"][()]
        strain = h["strain_z"][()]
        ratio = h["stress_ratio"][()]
        pairs = h["grain_pair_contacts"][()]
    rows = np.flatnonzero(st == stage)
    if rows.size == 0:
        raise SystemExit(f"{path}/results.h5: no history rows in stage {stage}")
    start = strain[rows[0] - 1] if rows[0] > 0 else None
    return start, strain[rows], ratio[rows], pairs[rows]


def first_opening(pairs):
    """Index of the first row with fewer grain pairs in contact than the stage began
    with, or None."""
    opened = np.flatnonzero(pairs < pairs[0])
    return int(opened[0]) if opened.size else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="DIR or DIR=LABEL")
    ap.add_argument("--out", required=True)
    ap.add_argument("--stage", type=int, default=2, help="the shearing stage (1-based)")
    ap.add_argument("--theory", type=float, help="theoretical peak σ1/σ3 (a line)")
    ap.add_argument("--theory-label", default="theory")
    a = ap.parse_args()
    runs = [(path, label or path) for path, _, label in (r.partition("=") for r in a.runs)]
    curves = [stage_rows(path, a.stage) for path, _ in runs]
    shared = next((start for start, _, _, _ in curves if start is not None), None)
    if shared is None:
        raise SystemExit("no run has a history row before the stage: its start is unknown")
    def vs_theory(value):
        return f" ({100 * (value / a.theory - 1):+.2f} % vs {a.theory})" if a.theory else ""

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (path, label), (start, strain, ratio, pairs) in zip(runs, curves):
        if start is None:
            print(f"{label}: no row before stage {a.stage}, its start taken from the first run")
        eps = strain - (shared if start is None else start)
        k = int(np.argmax(ratio))
        line = ax.plot(eps * 1e5, ratio, marker=".", label=label)[0]
        print(f"{label}: sampled peak {ratio[k]:.4f} at axial strain {eps[k]:.3e}"
              + vs_theory(ratio[k]))
        g = first_opening(pairs)
        if g is not None:
            opened = f"{int(pairs[0] - pairs[g])} of {int(pairs[0])} pairs"
            ax.plot(eps[g] * 1e5, ratio[g], "o", mfc="none", ms=10, color=line.get_color(),
                    label=f"{label}: first gap opens ({opened})")
            print(f"{label}: first gap opens by axial strain {eps[g]:.3e}, σ1/σ3 {ratio[g]:.4f} "
                  f"(previous row {ratio[g - 1]:.4f}); {opened} open" + vs_theory(ratio[g]))
    if a.theory:
        ax.axhline(a.theory, color="k", ls="--", lw=1, label=f"{a.theory_label}: {a.theory}")
    ax.set_xlabel("axial strain since the stage began (10⁻⁵)")
    ax.set_ylabel("σ1/σ3 (–)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


if __name__ == "__main__":
    main()
