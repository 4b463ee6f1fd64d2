#!/usr/bin/env python3
"""Plastic work of one elastic-plastic contact at given normal forces, per meshing ratio.

Reads the runs of `mufe validate plastic_spheres` (two identical spheres pressed together,
DIR/plastic_spheres/mr_<MR>/results.h5) and prints, for each MR, the plastic dissipation
ALLPD and the recoverable strain energy ALLSE of the pair when the loading leg first
reaches each force. With the forces of an FCC packing's contacts this says how fine the
contacts of a cell must be meshed for its plastic dissipation to converge (docs/BENCHMARKS.md,
"Energy study").

    MUFE_PLASTIC_SPHERES_TUNE=peak=20 mufe validate plastic_spheres --mr 4,2,1,0.5,0.25 --out DIR
    python3 scripts/contact_dissipation.py DIR --sigma 5e4 --radius 1.1e-3

--sigma and --radius give the contact forces of an FCC packing under isotropic stress σ
(F = √2 σ R², every contact alike) and under the axial stress ratio --ratio (the 8 contacts
inclined to the axis: F = √2 σ1 R²).
"""

import argparse
import glob
import math
import os
import sys

import h5py
import numpy as np


def first_reach(force, values, target):
    """values at the first row of the loading leg where the force reaches target."""
    peak = int(np.argmax(force))
    reached = np.nonzero(force[: peak + 1] >= target)[0]
    if len(reached) == 0:
        return float("nan")
    return float(values[reached[0]])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", help="--out directory of mufe validate plastic_spheres")
    ap.add_argument("--sigma", type=float, required=True, help="confining stress σ3 (Pa)")
    ap.add_argument("--radius", type=float, required=True, help="sphere radius R (m)")
    ap.add_argument("--ratio", type=float, default=3.0, help="σ1/σ3 at the peak (–)")
    args = ap.parse_args()

    iso = math.sqrt(2.0) * args.sigma * args.radius**2
    axial = args.ratio * iso
    runs = glob.glob(os.path.join(args.dir, "plastic_spheres", "mr_*", "results.h5"))
    if not runs:
        sys.exit(f"error: {args.dir}: no plastic_spheres/mr_*/results.h5")
    runs.sort(key=lambda p: -float(p.split("mr_")[-1].split("/")[0]))
    print(f"contact forces: isotropic {iso:.4f} N, inclined contacts at σ1/σ3 = {args.ratio}: {axial:.4f} N")
    print("| MR = s/ac | elements | F (N) | ALLPD (nJ) | ALLSE (nJ) | ALLPD/(ALLPD+ALLSE) | F (N) | ALLPD (nJ) | ALLSE (nJ) | ALLPD/(ALLPD+ALLSE) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in runs:
        mr = path.split("mr_")[-1].split("/")[0]
        with h5py.File(path, "r") as f:
            h = f["history"]
            force = -h["drive_force_z"][:]
            plastic = h["plastic_dissipation"][:]
            elastic = h["recoverable_strain_energy"][:]
            elements = f["mesh/tetrahedra"].shape[0]
        cells = [mr, str(elements)]
        for target in (iso, axial):
            wp = first_reach(force, plastic, target) * 1e9
            se = first_reach(force, elastic, target) * 1e9
            share = wp / (wp + se) if wp + se > 0 else float("nan")
            cells += [f"{target:.4f}", f"{wp:.3f}", f"{se:.3f}", f"{share:.3f}"]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
