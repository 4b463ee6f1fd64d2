#!/usr/bin/env python3
"""Render one frame of a mufe run as a PNG: the deformed grain surfaces coloured by the
von Mises stress of the element under each surface facet (a headless stand-in for a
ParaView screenshot; ParaView opens DIR/results.xdmf directly).

How to run:  scripts/render_frame.py DIR [--frame N|last] [--scale S] [--out FILE.png]
Needs h5py and matplotlib (pip install h5py matplotlib). Displacements are drawn S times
their size (default 1).
"""
import argparse
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def surface_faces(tets):
    """Boundary triangles (faces of exactly one tet) and the tet each belongs to."""
    local = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    faces = tets[:, local].reshape(-1, 3)
    owner = np.repeat(np.arange(len(tets)), 4)
    key = np.sort(faces, axis=1)
    _, index, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    once = index[counts == 1]
    return faces[once], owner[once]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dir")
    p.add_argument("--frame", default="last")
    p.add_argument("--scale", type=float, default=1.0)
    p.add_argument("--out", default=None)
    a = p.parse_args()
    f = h5py.File(f"{a.dir}/results.h5", "r")
    names = sorted(f["frames"].keys())
    name = names[-1] if a.frame == "last" else f"{int(a.frame):06d}"
    if name not in f["frames"]:
        sys.exit(f"error: {a.dir}/results.h5: no frame {a.frame} (have {len(names)})")
    frame = f["frames"][name]
    x = f["mesh/nodes"][:] + a.scale * frame["displacement"][:]
    faces, owner = surface_faces(f["mesh/tetrahedra"][:].astype(np.int64))
    vm = frame["von_mises_stress"][:][owner] / 1e6
    t = frame.attrs["time"]

    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    norm = matplotlib.colors.Normalize(vmin=0.0, vmax=max(float(vm.max()), 1e-12))
    colours = plt.cm.viridis(norm(vm))
    ax.add_collection3d(Poly3DCollection(x[faces] * 1e3, facecolors=colours, edgecolor="none"))
    lo, hi = x.min(axis=0) * 1e3, x.max(axis=0) * 1e3
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_lim(c - half, c + half)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.view_init(elev=20, azim=-60)
    sm = plt.cm.ScalarMappable(norm=norm, cmap="viridis")
    fig.colorbar(sm, ax=ax, shrink=0.6, label="von Mises stress (MPa)")
    scale = "" if a.scale == 1.0 else f", displacements ×{a.scale:g}"
    ax.set_title(f"{a.dir}: frame {name}, t = {t * 1e6:.3f} µs{scale}")
    out = a.out or f"{a.dir}/frame_{name}.png"
    fig.savefig(out, dpi=110, bbox_inches="tight")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
