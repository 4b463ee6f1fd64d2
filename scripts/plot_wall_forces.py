#!/usr/bin/env python3
"""Plot the walls' normal forces of a mufe run against time, one panel per stage span
marked, with the grain-pair contact count beside them: how the load a moving wall puts
in reaches the floor and the side walls (docs/SHAPES.md, "Demo").

How to run:  scripts/plot_wall_forces.py DIR [--out FILE.png] [--from-stage N]
Needs h5py and matplotlib (pip install h5py matplotlib). DIR holds results.h5.
"""
import argparse

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--out")
    ap.add_argument("--from-stage", type=int, default=1, help="first stage drawn (1-based)")
    a = ap.parse_args()
    with h5py.File(f"{a.dir}/results.h5", "r") as f:
        h = f["history"]
        t = h["time"][()]
        stage = h["stage"][()]
        keep = stage >= a.from_stage
        walls = sorted({k[: -len("_force_x")] for k in h if k.endswith("_force_x")})
        fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 6), sharex=True,
                                     gridspec_kw={"height_ratios": [3, 1]})
        for w in walls:
            # the force each wall exerts on the grains, along its inward normal
            f3 = np.stack([h[f"{w}_force_{c}"][()] for c in "xyz"], axis=1)
            n = np.abs(f3).max(axis=0)
            axis = int(np.argmax(n))
            sign = -1.0 if w in ("top", "x_max", "y_max", "z_max") else 1.0
            ax.plot(t[keep] * 1e3, sign * f3[keep, axis], label=w, lw=1)
        ax.set_ylabel("wall force on the grains (N)")
        ax.legend(ncol=3, fontsize=8)
        ax.grid(alpha=0.3)
        bx.plot(t[keep] * 1e3, h["grain_pair_contacts"][()][keep], color="k", lw=1)
        bx.set_ylabel("grain pairs\nin contact")
        bx.set_xlabel("t (ms)")
        bx.grid(alpha=0.3)
        for s in np.unique(stage[keep]):
            t0 = t[keep][stage[keep] == s][0] * 1e3
            for x in (ax, bx):
                x.axvline(t0, color="0.6", ls=":", lw=0.8)
            ax.text(t0, ax.get_ylim()[1], f" {int(s)}", va="top", fontsize=8, color="0.4")
        fig.suptitle(f"{a.dir}: wall forces by stage")
        fig.tight_layout()
        out = a.out or f"{a.dir}/wall_forces.png"
        fig.savefig(out, dpi=110)
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
