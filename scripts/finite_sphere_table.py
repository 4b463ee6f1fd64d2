#!/usr/bin/env python3
"""Reference table: a linear elastic sphere squeezed between two rigid frictionless plates.

Independent of mufe (numpy + scipy only). Developer tool; CI never runs it.

Problem. Isotropic linear (small-strain) elastic sphere, radius R, Young's modulus E,
Poisson ratio nu, pressed between two rigid frictionless flat plates, each plate
approaching the centre plane by delta. By symmetry: the upper hemisphere with u_z = 0
on the equatorial plane z = 0, pressed at its pole (0, R) against a rigid frictionless
flat. The result is F / (E* R^2) = f(delta / R, nu), E* = E / (1 - nu^2).

Method (see docs/FINITE_SPHERE.md).
  * Axisymmetric FE in (r, z), 6-node isoparametric triangles for the displacement and
    continuous linear pressure on the corner nodes (Taylor-Hood P2/P1 mixed u-p
    formulation: sigma = 2 mu dev(eps) + p I, p = K tr(eps)); no locking as nu -> 1/2.
    Edges on the sphere are curved (midside nodes on the circle). 7-point (degree 5)
    quadrature, 2 pi r weight.
  * Mesh: block A = polar grid centred on the pole, ring radii uniform (step
    (q - 1) rho_1) inside rho_1 and geometric (ratio q) from rho_1 to 0.6 R, so the
    element size at the contact edge is a fixed fraction (q - 1) of the contact radius for
    every load; angular lines graded towards the surface. Block B = transfinite
    (Coons) patch from the arc rho = 0.6 R to the equatorial plane.
  * Boundary conditions: u_r = 0 on the axis, u_z = 0 on z = 0.
  * Contact: every surface node with r <= r_cand is a candidate. One sparse LU of the
    saddle-point matrix and one solve per candidate give the (dense, SPD) flexibility
    matrix C (downward u_z at node i per unit downward force at node j). For each delta
    the exact nodal frictionless unilateral problem
        lambda >= 0,  w = C lambda - (delta - g0) >= 0,  lambda . w = 0
    (g0 = initial gap of the node to the flat tangent at the pole) is solved by a
    primal-dual active-set iteration (with an NNLS fallback) and checked against the
    KKT conditions. Because the obstacle is flat, the gap does not depend on u_r: the
    nodal constraint is exact in small-strain kinematics. F = sum(lambda).
  * Contact radius: between the outermost node in contact (r_in) and the first free node
    r1: least-squares fit of the gaps of the free nodes within 1.15 a to the edge
    asymptote w = (r - a)^(3/2) (c0 + c1 (r - a) / a), scanning a over [r_in, r1).
    Good to ~0.2 % (node spacing at the edge 0.5 % of a); F is good to ~0.005 %.

Usage:
    python3 -m venv /tmp/fsvenv && /tmp/fsvenv/bin/pip install numpy scipy
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 nice -n 10 \\
        /tmp/fsvenv/bin/python scripts/finite_sphere_table.py table     # writes the CSV
    ... scripts/finite_sphere_table.py converge --nu 0.22             # mesh study
    ... scripts/finite_sphere_table.py compare                          # vs shipped nu=0.22
    ... scripts/finite_sphere_table.py loo                              # interpolation check
"""
import argparse
import datetime
import math
import pathlib
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

REPO = pathlib.Path(__file__).resolve().parent.parent
TABLE = REPO / "jobs/validation/hertz_finite_sphere_table.csv"
SHIPPED = REPO / "jobs/validation/hertz_finite_sphere_reference.csv"

NUS = [0.00, 0.05, 0.10, 0.15, 0.20, 0.22, 0.25, 0.30, 0.35, 0.40, 0.45, 0.49]
# delta/R = 10^(-4.4 + 0.1 k), k = 0..26: 3.98e-5 .. 1.58e-2 (a/R ~ 0.0063 .. 0.129)
LOG_DELTAS = [round(-4.4 + 0.1 * k, 10) for k in range(27)]

# Mesh levels: q = radial ratio of the graded rings (element size at the contact edge
# ~ (q - 1) a), ang = growth of the angular spacing from the surface to the axis.
LEVELS = {
    "coarse": dict(q=1.04, ang=1.08),
    "medium": dict(q=1.02, ang=1.05),
    "fine": dict(q=1.01, ang=1.03),
    "xfine": dict(q=1.006, ang=1.02),
}
RHO_1 = 3.0e-3      # rings geometric above this pole distance (/R); a_min/R ~ 0.007
RHO_A = 0.6         # outer radius of the polar block (/R)
R_CAND = 0.145      # contact candidates: surface nodes with r <= R_CAND (/R)


def log(*a):
    print(*a, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- mesh
def graded_spacing(q, rho_1, rho_a):
    """Ring radii: uniform step (q-1) rho_1 up to rho_1, geometric ratio q to rho_a."""
    n_in = max(4, int(round(1.0 / (q - 1.0))))
    inner = np.linspace(0.0, rho_1, n_in + 1)
    n_out = int(math.ceil(math.log(rho_a / rho_1) / math.log(q)))
    outer = rho_1 * (rho_a / rho_1) ** (np.arange(1, n_out + 1) / n_out)
    return np.concatenate([inner, outer])


def angular_spacing(dtheta0, growth, total=math.pi / 2):
    """psi in [0, 1] (0 = axis, 1 = surface): first step at the surface ~ dtheta0
    (radians of a ~90 degree fan), then growing by `growth` towards the axis."""
    steps = [dtheta0]
    while sum(steps) < total:
        steps.append(steps[-1] * growth)
    steps = np.array(steps)
    steps *= 1.0 / steps.sum()
    psi = 1.0 - np.concatenate([[0.0], np.cumsum(steps)])
    psi[-1] = 0.0
    return psi[::-1].copy()  # increasing, 0 .. 1


def build_mesh(q, ang, R=1.0):
    """Structured corner grid -> P2 triangles. Returns nodes (N,2) [r,z], tri (ne,6),
    ncorner (corner nodes are 0..ncorner-1)."""
    rho = graded_spacing(q, RHO_1, RHO_A) * R
    psi = angular_spacing(q - 1.0, ang)
    nj = len(psi)
    # block A: polar about the pole P = (0, R); theta from the downward axis
    th_max = math.pi / 2 - np.arcsin(rho / (2 * R))
    TH = th_max[:, None] * psi[None, :]
    XA = np.stack([rho[:, None] * np.sin(TH), R - rho[:, None] * np.cos(TH)], axis=-1)
    # block B: Coons patch from arc rho = RHO_A (t = 0) to the equator (t = 1)
    rhoA = rho[-1]
    hA = rho[-1] - rho[-2]
    LB = R - rhoA
    M = max(8, int(math.ceil(LB / hA)))
    t = np.linspace(0.0, 1.0, M + 1)
    bot = XA[-1]                                              # (nj, 2)
    top = np.stack([R * psi, np.zeros(nj)], axis=-1)          # equator
    phiA = 2 * math.asin(rhoA / (2 * R))
    phi = phiA + t * (math.pi / 2 - phiA)
    left = np.stack([np.zeros_like(t), (R - rhoA) * (1 - t)], axis=-1)   # axis
    right = np.stack([R * np.sin(phi), R * np.cos(phi)], axis=-1)        # sphere
    T, S = t[:, None, None], psi[None, :, None]
    XB = ((1 - T) * bot[None] + T * top[None] + (1 - S) * left[:, None] + S * right[:, None]
          - ((1 - S) * (1 - T) * bot[0] + S * (1 - T) * bot[-1]
             + (1 - S) * T * top[0] + S * T * top[-1]))
    G = np.concatenate([XA, XB[1:]], axis=0)                  # (ni, nj, 2)
    ni = G.shape[0]
    # corner nodes, merging the collapsed pole ring (i = 0)
    idx = np.arange(ni * nj).reshape(ni, nj) - (nj - 1)
    idx[0, :] = 0
    corners = np.concatenate([G[0, :1], G[1:].reshape(-1, 2)])
    tris = []
    for i in range(ni - 1):
        a, b = idx[i, :-1], idx[i + 1, :-1]
        c, d = idx[i + 1, 1:], idx[i, 1:]
        tris.append(np.stack([a, b, c], 1))
        if i > 0:
            tris.append(np.stack([a, c, d], 1))
    tri3 = np.concatenate(tris)
    # orient counter-clockwise in (r, z)
    P = corners[tri3]
    ar = ((P[:, 1, 0] - P[:, 0, 0]) * (P[:, 2, 1] - P[:, 0, 1])
          - (P[:, 2, 0] - P[:, 0, 0]) * (P[:, 1, 1] - P[:, 0, 1]))
    flip = ar < 0
    tri3[flip] = tri3[flip][:, [0, 2, 1]]
    # midside nodes
    nc = len(corners)
    edges = np.concatenate([tri3[:, [0, 1]], tri3[:, [1, 2]], tri3[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    uniq, inv = np.unique(key[:, 0] * nc + key[:, 1], return_inverse=True)
    e0, e1 = uniq // nc, uniq % nc
    mid = 0.5 * (corners[e0] + corners[e1])
    # curved boundary edges on the sphere
    rad = np.hypot(corners[:, 0], corners[:, 1])
    on_sph = (np.abs(rad[e0] - R) < 1e-12 * R) & (np.abs(rad[e1] - R) < 1e-12 * R)
    mid[on_sph] *= (R / np.hypot(mid[on_sph, 0], mid[on_sph, 1]))[:, None]
    nodes = np.concatenate([corners, mid])
    ne = len(tri3)
    m = nc + inv.reshape(3, ne).T
    tri = np.concatenate([tri3, m], axis=1)
    return nodes, tri, nc


# ------------------------------------------------------------------------ assembly
_A, _B = 0.059715871789770, 0.470142064105115
_C, _D = 0.797426985353087, 0.101286507323456
QP = np.array([[1 / 3, 1 / 3], [_B, _B], [_A, _B], [_B, _A], [_D, _D], [_C, _D], [_D, _C]])
QW = 0.5 * np.array([0.225] + [0.132394152788506] * 3 + [0.125939180544827] * 3)


def shape_p2(x, y):
    l1 = 1 - x - y
    N = np.array([l1 * (2 * l1 - 1), x * (2 * x - 1), y * (2 * y - 1), 4 * l1 * x, 4 * x * y, 4 * y * l1])
    dx = np.array([-(4 * l1 - 1), 4 * x - 1, 0.0, 4 * (l1 - x), 4 * y, -4 * y])
    dy = np.array([-(4 * l1 - 1), 0.0, 4 * y - 1, -4 * x, 4 * x, 4 * (l1 - y)])
    return N, dx, dy


def assemble(nodes, tri, nc, nu, E=1.0, chunk=40000, mixed=True):
    """Saddle-point matrix of the P2/P1 axisymmetric u-p formulation (2 pi r included).
    DOFs: u_r(n) = 2n, u_z(n) = 2n+1, p(corner c) = 2N + c."""
    mu = E / (2 * (1 + nu))
    kb = E / (3 * (1 - 2 * nu)) if nu < 0.5 else np.inf
    N_nodes = len(nodes)
    m4 = np.array([1.0, 1.0, 1.0, 0.0])
    Ddev = mu * (2 * np.diag([1.0, 1.0, 1.0, 0.5]) - (2.0 / 3.0) * np.outer(m4, m4))
    if not mixed:   # plain P2 displacement formulation (cross-check; locks as nu -> 1/2)
        Ddev = Ddev + kb * np.outer(m4, m4)
    rows, cols, vals = [], [], []
    for s0 in range(0, len(tri), chunk):
        T = tri[s0:s0 + chunk]
        X = nodes[T]                                  # (ne, 6, 2)
        ne = len(T)
        Ke = np.zeros((ne, 15, 15))
        for (x, y), w in zip(QP, QW):
            N, dx, dy = shape_p2(x, y)
            J = np.einsum("eka,kb->eab", X, np.stack([dx, dy], 1))   # J[a,b] = dX_a/dxi_b
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            assert (det > 0).all(), "inverted element"
            inv = np.empty_like(J)
            inv[:, 0, 0], inv[:, 1, 1] = J[:, 1, 1] / det, J[:, 0, 0] / det
            inv[:, 0, 1], inv[:, 1, 0] = -J[:, 0, 1] / det, -J[:, 1, 0] / det
            dN = np.einsum("kb,eba->eka", np.stack([dx, dy], 1), inv)  # dN/dr, dN/dz
            r = X[:, :, 0] @ N
            B = np.zeros((ne, 4, 12))
            B[:, 0, 0::2] = dN[:, :, 0]
            B[:, 1, 1::2] = dN[:, :, 1]
            B[:, 2, 0::2] = N[None, :] / r[:, None]
            B[:, 3, 0::2] = dN[:, :, 1]
            B[:, 3, 1::2] = dN[:, :, 0]
            f = (w * det * 2 * math.pi * r)[:, None, None]
            Ke[:, :12, :12] += f * np.einsum("eia,ij,ejb->eab", B, Ddev, B)
            if not mixed:
                continue
            Np = np.array([1 - x - y, x, y])
            div = np.einsum("i,eia->ea", m4, B)
            bp = f * Np[None, :, None] * div[:, None, :]    # (ne, 3, 12)
            Ke[:, 12:, :12] += bp
            Ke[:, :12, 12:] += bp.transpose(0, 2, 1)
            if np.isfinite(kb):
                Ke[:, 12:, 12:] -= f * np.outer(Np, Np)[None] / kb
        dof = np.empty((ne, 15), dtype=np.int64)
        dof[:, 0:12:2] = 2 * T
        dof[:, 1:12:2] = 2 * T + 1
        dof[:, 12:] = 2 * N_nodes + T[:, :3]
        rows.append(np.repeat(dof, 15, axis=1).ravel())
        cols.append(np.tile(dof, (1, 15)).ravel())
        vals.append(Ke.ravel())
    n = 2 * N_nodes + nc
    if not mixed:   # pressure rows/columns are empty: drop them
        rr, cc, vv = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        keep = (rr < 2 * N_nodes) & (cc < 2 * N_nodes)
        rows, cols, vals = [rr[keep]], [cc[keep]], [vv[keep]]
        n = 2 * N_nodes
    K = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsc()
    K.sum_duplicates()
    return K


# ------------------------------------------------------------------- flexibility
class Model:
    def __init__(self, level, nu, R=1.0, verbose=True, mixed=True):
        t0 = time.time()
        p = LEVELS[level]
        self.level, self.nu, self.R = level, nu, R
        nodes, tri, nc = build_mesh(p["q"], p["ang"], R)
        self.nodes, self.tri = nodes, tri
        K = assemble(nodes, tri, nc, nu, mixed=mixed)
        Nn = len(nodes)
        tol = 1e-12 * R
        fixed = np.concatenate([2 * np.where(np.abs(nodes[:, 0]) < tol)[0],
                                2 * np.where(np.abs(nodes[:, 1]) < tol)[0] + 1])
        free = np.setdiff1d(np.arange(K.shape[0]), fixed)
        Kf = K[free][:, free].tocsc()
        # contact candidates: sphere-surface nodes with r <= R_CAND, sorted by r
        rad = np.hypot(nodes[:, 0], nodes[:, 1])
        cand = np.where((np.abs(rad - R) < tol) & (nodes[:, 0] <= R_CAND * R) & (nodes[:, 1] > 0))[0]
        cand = cand[np.argsort(nodes[cand, 0])]
        self.cand_r = nodes[cand, 0]
        self.g0 = R - nodes[cand, 1]
        pos = np.full(K.shape[0], -1)
        pos[free] = np.arange(len(free))
        cdof = pos[2 * cand + 1]
        assert (cdof >= 0).all()
        t1 = time.time()
        # symmetric-mode LU (minimum degree on K + K^T, no row pivoting): small fill for
        # this saddle-point matrix; accuracy restored and checked by iterative refinement
        lu = spla.splu(Kf, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options=dict(SymmetricMode=True))
        t2 = time.time()
        nca = len(cand)
        C = np.empty((nca, nca))
        blk = 64
        self.resid = 0.0
        for s0 in range(0, nca, blk):
            cols = cdof[s0:s0 + blk]
            rhs = np.zeros((Kf.shape[0], len(cols)))
            rhs[cols, np.arange(len(cols))] = 1.0      # downward force -> sign cancels
            X = lu.solve(rhs)
            for _ in range(3):                          # iterative refinement if needed
                res = np.abs(rhs - Kf @ X).max()
                if res < 1e-11:
                    break
                X += lu.solve(rhs - Kf @ X)
            res = np.abs(rhs - Kf @ X).max()
            self.resid = max(self.resid, res)
            C[:, s0:s0 + len(cols)] = X[cdof]
        assert self.resid < 1e-8, self.resid
        t3 = time.time()
        self.asym = np.abs(C - C.T).max() / np.abs(C).max()
        self.C = 0.5 * (C + C.T)
        self.ndof = Kf.shape[0]
        self.nel = len(tri)
        self.nnz_lu = lu.L.nnz + lu.U.nnz
        self.times = (t1 - t0, t2 - t1, t3 - t2)
        self._act = None
        if verbose:
            log(f"[{level} nu={nu}] {len(tri)} P2 triangles, {Nn} nodes, {self.ndof} dofs, "
                f"{nca} candidates; mesh+assembly {t1 - t0:.1f}s, LU {t2 - t1:.1f}s "
                f"(nnz {self.nnz_lu / 1e6:.1f}M), flexibility {t3 - t2:.1f}s, asym {self.asym:.1e}, "
                f"residual {self.resid:.1e}")

    def solve(self, delta):
        """Exact nodal frictionless contact for plate approach delta (each plate)."""
        C, d = self.C, delta - self.g0
        n = len(d)
        act = d > 0 if self._act is None else self._act.copy()
        lam = np.zeros(n)
        ok = False
        for _ in range(100):
            lam[:] = 0.0
            if act.any():
                lam[act] = np.linalg.solve(C[np.ix_(act, act)], d[act])
            w = C @ lam - d
            new = np.where(act, lam > 0, w < 0)
            if (new == act).all():
                ok = True
                break
            act = new
        scale = max(np.abs(d).max(), 1e-300)
        if not ok or lam.min() < -1e-12 * lam.max() or w.min() < -1e-9 * scale:
            from scipy.optimize import nnls
            L = np.linalg.cholesky(C)
            lam, _ = nnls(L.T, np.linalg.solve(L, d), maxiter=50 * n)
            w = C @ lam - d
            act = lam > 0
        # KKT check
        assert lam.min() >= -1e-12 * lam.max()
        assert w.min() >= -1e-8 * scale, w.min() / scale
        assert abs(lam @ w) <= 1e-8 * lam.sum() * scale
        self._act = act
        F = lam.sum()
        if act[-1]:
            raise RuntimeError("contact reached the last candidate node: raise R_CAND")
        a = self.contact_radius(act, w)
        return F, a, lam, w

    def contact_radius(self, act, w):
        """Contact edge between the outermost contact node r_in and the first free node
        r1: least-squares fit of the gaps of the free nodes with r < 1.15 a to the edge
        asymptote w = (r - a)^(3/2) (c0 + c1 (r - a) / a), scanning a in [r_in, r1)."""
        r = self.cand_r
        i_in = np.where(act)[0].max()
        r_in, r1 = r[i_in], r[i_in + 1]
        A = np.linspace(r_in, r1, 201)[:-1]
        best, a_best = np.inf, r_in
        for a in A:
            sel = (r > a) & (r < 1.15 * a)
            x = r[sel] - a
            M = np.stack([x ** 1.5, x ** 2.5 / a], 1)
            c, *_ = np.linalg.lstsq(M, w[sel], rcond=None)
            e = ((M @ c - w[sel]) ** 2).sum()
            if e < best:
                best, a_best = e, a
        return float(a_best)


def hertz_F(delta, R=1.0, Estar=1.0):
    return 4.0 / 3.0 * Estar * math.sqrt(R) * delta ** 1.5


def run_model(level, nu, deltas):
    m = Model(level, nu)
    Estar = 1.0 / (1 - nu ** 2)
    out = []
    for dl in deltas:
        F, a, _, _ = m.solve(dl)
        out.append((dl, F / Estar, a))
    return m, out


# ------------------------------------------------------------------- commands
def read_shipped():
    rows = []
    for line in SHIPPED.read_text().splitlines():
        if line.startswith("#") or line.startswith("delta_um") or not line.strip():
            continue
        v = [float(x) for x in line.split(",")]
        rows.append(v)
    return np.array(rows)


def cmd_converge(args):
    deltas = [10 ** x for x in LOG_DELTAS[1::5]]
    res = {}
    for lev in args.levels:
        m, out = run_model(lev, args.nu, deltas)
        res[lev] = np.array(out)
    print(f"# convergence, nu = {args.nu}: F/(E* R^2) and (F - F_ref)/F_ref with ref = {args.levels[-1]}")
    ref = res[args.levels[-1]]
    print("delta/R      a/R(ref)  " + "  ".join(f"{l:>22s}" for l in args.levels))
    for k, dl in enumerate(deltas):
        s = f"{dl:.4e}  {ref[k, 2]:.5f}  "
        for lev in args.levels:
            F = res[lev][k, 1]
            s += f"  {F:.7e} {100 * (F / ref[k, 1] - 1):+.4f}%"
        print(s)


def cmd_compare(args):
    ship = read_shipped()
    Rm, E, nu = 1.1e-3, 63e9, 0.22
    Estar = E / (1 - nu ** 2)
    deltas = ship[:, 0] * 1e-6 / Rm
    print("# shipped nu=0.22 table vs this method; F in N (R=1.1 mm, E=63 GPa)")
    res = {}
    for lev in args.levels:
        m, out = run_model(lev, nu, deltas)
        res[lev] = np.array(out)
    print("delta_um   F_shipped   " + "  ".join(f"{l}: F_N  rel.diff  a_um" for l in args.levels))
    for k in range(len(ship)):
        s = f"{ship[k, 0]:7.3f}  {ship[k, 1]:.6g}"
        for lev in args.levels:
            F = res[lev][k, 1] * Estar * Rm ** 2
            s += f"   {F:.6g} {100 * (F / ship[k, 1] - 1):+.4f}% {res[lev][k, 2] * Rm * 1e6:7.3f}"
        print(s)
    for lev in args.levels:
        F = res[lev][:, 1] * Estar * Rm ** 2
        d = np.abs(F / ship[:, 1] - 1) * 100
        print(f"# {lev}: max |rel diff| {d.max():.4f} %, median {np.median(d):.4f} %, rms {np.sqrt((d ** 2).mean()):.4f} %")
    if pathlib.Path(args.table).exists():
        tab = load_table(args.table)
        assert tab[:, 1].min() <= deltas.min() and deltas.max() <= tab[:, 1].max(), "outside the table"
        F = np.array([interp_table(tab, nu, dl) for dl in deltas]) * Estar * Rm ** 2
        d = np.abs(F / ship[:, 1] - 1) * 100
        print(f"# table {pathlib.Path(args.table).name} interpolated (log-log) at the shipped delta: "
              f"max |rel diff| {d.max():.4f} %, median {np.median(d):.4f} %")


def cmd_table(args):
    deltas = [10 ** x for x in LOG_DELTAS]
    lines, conv = [], []
    t0 = time.time()
    info = None
    for nu in args.nus:
        m, out = run_model(args.level, nu, deltas)
        info = m
        for dl, F, a in out:
            lines.append(f"{nu:.2f},{dl:.7e},{F:.9e},{a:.7e}")
        if args.check_level:
            _, chk = run_model(args.check_level, nu, deltas)
            dF = max(abs(c[1] / o[1] - 1) for o, c in zip(out, chk))
            da = max(abs(c[2] / o[2] - 1) for o, c in zip(out, chk))
            conv.append(f"{nu:.2f}: {100 * dF:.4f}/{100 * da:.3f}")
            log(f"nu={nu}: max |F_{args.check_level}/F_{args.level} - 1| = {100 * dF:.4f} %, a: {100 * da:.3f} %")
    el = time.time() - t0
    p = LEVELS[args.level]
    cmd = "scripts/finite_sphere_table.py table --level %s" % args.level
    if args.check_level:
        cmd += " --check-level %s" % args.check_level
    hdr = [
        "# Linear elastic sphere (radius R, Young's modulus E, Poisson ratio nu) squeezed between two rigid",
        "# frictionless flat plates; delta = approach of EACH plate to the centre plane; F = force on a plate;",
        "# E* = E/(1-nu^2). Half-space Hertz: F_H/(E* R^2) = (4/3) (delta/R)^(3/2), a_H/R = (delta/R)^(1/2).",
        "# Method (independent of mufe; scripts/finite_sphere_table.py, docs/FINITE_SPHERE.md): axisymmetric FE of",
        "#   the hemisphere, u_z = 0 on the equator, u_r = 0 on the axis; Taylor-Hood P2/P1 (u-p) triangles with",
        "#   curved boundary edges; exact nodal frictionless unilateral contact with the flat, solved on the",
        "#   flexibility matrix of all surface nodes with r <= %.3f R (active set, KKT checked)." % R_CAND,
        "# Mesh '%s': %d P2 triangles, %d dofs; rings about the pole with ratio q = %.3f (element size at the"
        % (args.level, info.nel, info.ndof, p["q"]),
        "#   contact edge = %.0f %% of a at every load; uniform below %.0e R), angular growth %.2f to the axis."
        % (100 * (p["q"] - 1), RHO_1, p["ang"]),
    ]
    if conv:
        q2 = LEVELS[args.check_level]["q"]
        hdr += ["# Convergence: max |relative difference| F/a in %% between this mesh and mesh '%s' (q = %.3f)," % (args.check_level, q2),
                "#   per nu: " + "; ".join(conv[:6])]
        if conv[6:]:
            hdr.append("#   " + "; ".join(conv[6:]))
    hdr += [
        "# a_over_R: contact radius between the outermost node in contact and the first free node, from a",
        "#   least-squares fit of the gaps of the free nodes within 1.15 a to w = (r-a)^1.5 (c0 + c1 (r-a)/a).",
        "# Interpolate linearly in nu and log-log in delta_over_R (error estimates in docs/FINITE_SPHERE.md).",
        "# Date: 2026-11-22. Made by: OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 nice -n 10 python3 %s (%.0f s)" % (cmd, el),
        "nu,delta_over_R,F_over_EstarR2,a_over_R",
    ]
    out = pathlib.Path(args.out)
    out.write_text("\n".join(hdr + lines) + "\n")
    log(f"wrote {out} ({len(lines)} rows) in {el:.0f} s")


def load_table(path):
    rows = np.array([[float(x) for x in l.split(",")] for l in pathlib.Path(path).read_text().splitlines()
                     if l and not l.startswith("#") and not l.startswith("nu,")])
    return rows


def interp_table(tab, nu, dl, ratio=False, quad_nu=False):
    """Linear in nu (quadratic through the 3 nearest nu with quad_nu=True); in delta
    piecewise linear in log F vs log delta (log-log), or, with ratio=True, piecewise
    linear in F/F_H vs log delta."""
    nus = np.unique(tab[:, 0])

    def at_nu(n):
        t = tab[tab[:, 0] == n]
        x = np.log(t[:, 1])
        if ratio:
            fh = 4.0 / 3.0 * t[:, 1] ** 1.5
            return np.interp(math.log(dl), x, t[:, 2] / fh) * 4.0 / 3.0 * dl ** 1.5
        return math.exp(np.interp(math.log(dl), x, np.log(t[:, 2])))
    if np.isclose(nus, nu).any():
        return at_nu(nus[np.isclose(nus, nu)][0])
    if quad_nu:
        near = nus[np.argsort(np.abs(nus - nu))[:3]]
        val = 0.0
        for i, ni in enumerate(near):
            others = np.delete(near, i)
            val += at_nu(ni) * np.prod((nu - others) / (ni - others))
        return val
    j = int(np.clip(np.searchsorted(nus, nu) - 1, 0, len(nus) - 2))
    n0, n1 = nus[j], nus[j + 1]
    s = (nu - n0) / (n1 - n0)
    return (1 - s) * at_nu(n0) + s * at_nu(n1)


def cmd_loo(args):
    tab = load_table(args.table)
    nus = np.unique(tab[:, 0])
    for ratio in (False, True):
        name = "F/F_H linear in log(delta)" if ratio else "log F linear in log(delta)"
        print(f"## in delta: {name}; in nu: linear")
        print("# leave one nu out (interior), interpolate from its neighbours: max |rel err| over delta")
        worst_nu = 0.0
        for n in nus[1:-1]:
            sub = tab[tab[:, 0] != n]
            t = tab[tab[:, 0] == n]
            e = [abs(interp_table(sub, n, d, ratio) / F - 1) for d, F in t[:, 1:3]]
            worst_nu = max(worst_nu, max(e))
            print(f"  nu = {n:.2f} (gap {sub[:, 0][sub[:, 0] > n].min() - sub[:, 0][sub[:, 0] < n].max():.2f}): {100 * max(e):.4f} %")
        print("# leave one delta out (interior), interpolate from its neighbours (0.2 decade apart)")
        worst_d, med = 0.0, []
        for n in nus:
            t = tab[tab[:, 0] == n]
            e = []
            for k in range(1, len(t) - 1):
                sub = np.delete(t, k, axis=0)
                e.append(abs(interp_table(sub, n, t[k, 1], ratio) / t[k, 2] - 1))
            worst_d = max(worst_d, max(e))
            med.append(np.median(e))
            print(f"  nu = {n:.2f}: max {100 * max(e):.4f} %, median {100 * np.median(e):.4f} %")
        print(f"# worst: leave-one-nu-out {100 * worst_nu:.4f} %, leave-one-delta-out {100 * worst_d:.4f} % "
              f"(median {100 * np.median(med):.4f} %)")
    print("## in nu: quadratic through the 3 nearest remaining nu (log-log in delta)")
    worst = 0.0
    for n in nus[1:-1]:
        sub = tab[tab[:, 0] != n]
        t = tab[tab[:, 0] == n]
        e = [abs(interp_table(sub, n, d, quad_nu=True) / F - 1) for d, F in t[:, 1:3]]
        worst = max(worst, max(e))
        print(f"  nu = {n:.2f}: {100 * max(e):.4f} %")
    print(f"# worst: leave-one-nu-out (quadratic) {100 * worst:.4f} %")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("table", help="write the CSV table")
    a.add_argument("--level", default="fine", choices=LEVELS)
    a.add_argument("--nus", type=float, nargs="+", default=NUS)
    a.add_argument("--check-level", default="medium", help="second mesh for the convergence note ('' = none)")
    a.add_argument("--out", default=str(TABLE))
    a = sub.add_parser("converge", help="mesh convergence study")
    a.add_argument("--nu", type=float, default=0.22)
    a.add_argument("--levels", nargs="+", default=["coarse", "medium", "fine"])
    a = sub.add_parser("compare", help="compare with the shipped nu = 0.22 table")
    a.add_argument("--levels", nargs="*", default=["fine"])
    a.add_argument("--table", default=str(TABLE), help="also compare this table, interpolated")
    a = sub.add_parser("loo", help="leave-one-out interpolation check of the table")
    a.add_argument("--table", default=str(TABLE))
    args = ap.parse_args()
    {"table": cmd_table, "converge": cmd_converge, "compare": cmd_compare, "loo": cmd_loo}[args.cmd](args)


if __name__ == "__main__":
    main()
