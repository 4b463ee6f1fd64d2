#!/usr/bin/env python3
"""Generates jobs/validation/{hertz,mindlin,torsion,rolling}.toml.

Hertz: one glass sphere squeezed between two rigid frictionless plates.
Two-sphere cases: two identical glass spheres (THEORY.md material) touching at the origin.
The far hemisphere of the lower sphere is held fixed; the far hemisphere of the upper sphere
is driven rigidly: first down to the normal force N (displacement control; N is then
measured and used by the reference), then the case's motion. Velocity profiles are
trapezoids with raised-cosine ramps so the loading is smooth.

Meshes are fine only at the contact: a local refinement patch per contact whose seeding
`mufe validate` sets from the meshing ratio MR = s/(2R); the patch radius covers the
contact radius a at the case's load.

How to run:
    python3 scripts/gen_validation_scenes.py                 # rewrites the four scene files
    python3 scripts/gen_validation_scenes.py --out DIR --set rolling.vn=1.0 ...
        # variants for experiments: run them with MUFE_VALIDATION_SCENES=DIR mufe validate
"""
import argparse, math, pathlib

E, NU, RHO, MU, R = 63e9, 0.22, 2500.0, 0.22, 1.1e-3
G = E / (2 * (1 + NU))
E_FLAT = E / (1 - NU**2)

# Tunable parameters per case (times in s, speeds in m/s or rad/s, lengths in m).
PARAMS = {
    "hertz": dict(
        v_plate=0.6,          # plate speed after the ramp
        ramp=6.0e-6,          # raised-cosine ramp of the plate speed (0: constant speed)
        gap=0.0,              # initial gap between each plate and its pole
        delta_end=7.2e-6,     # plate travel covered by the duration (F_ref ≈ 55 N)
        target_dt=3.0e-9,     # mass scaling of the fine contact elements
        seeding=1.5e-4,       # global surface seeding
        refine_radius=1.0e-5, # fine zone around each pole (chord distance)
        growth=0.12,          # growth of the edge length beyond the fine zone
        damping=0.0,          # deformation damping (1/s)
        history_interval=2.5e-8,
    ),
    "mindlin": dict(
        force=5.0, approach_scale=0.92,
        vn=1.0, n_ramp=2.0e-6, settle=2.0e-6,     # normal approach of the drive, then rest
        vt=0.4, t_ramp=1.5e-6, amplitude=1.2,    # tangential amplitude in units of δt,max
        reversals=2,          # 1: unload to −amplitude; 2: then reload to +amplitude
        target_dt=2.0e-9, damping=2.0e6, seeding=2.75e-4,
        refine_radius=2.0e-5, growth=0.15, history_interval=2.0e-8,
        # held/driven parts: beyond the planes at ∓clamp·R from the contact (1 = the far
        # hemispheres). The half-space references leave out the compliance of the spheres
        # between the contact and the held parts; see docs/BENCHMARKS.md (Validation).
        clamp=0.5,
    ),
    "torsion": dict(
        force=70.0, approach_scale=0.92, vn=4.0, n_ramp=2.0e-6, settle=2.0e-6,
        twist_param=0.6,      # final G a² β/(μN) (c/a ≈ 0.1)
        cruise=5e-6, t_ramp=2.0e-6,
        target_dt=2.0e-9, damping=2.0e6, seeding=2.75e-4,
        refine_radius=1.1e-4, growth=0.3, history_interval=2.0e-8, clamp=0.5,
    ),
    "rolling": dict(
        force=70.0, approach_scale=0.92, vn=4.0, n_ramp=2.0e-6, settle=2.0e-6,
        amplitude=1.5,        # final Rθ in units of δt,max
        cruise=5e-6, t_ramp=2.0e-6,
        target_dt=2.0e-9, damping=2.0e6, seeding=2.75e-4,
        refine_radius=1.1e-4, growth=0.3, history_interval=2.0e-8, clamp=0.5,
    ),
}


def approach_pair(force):
    # two identical spheres: each behaves as a sphere on a rigid frictionless flat
    return 2 * (3 * force / (4 * E_FLAT * math.sqrt(R))) ** (2 / 3)


def contact_radius(force):
    return (3 * force * (R / 2) / (4 * (E_FLAT / 2))) ** (1 / 3)


RAMP_POINTS = 8


def trapezoid(t0, distance, vmax, ramp):
    """Velocity-time points moving `distance` (signed) from t0: raised-cosine ramps up and
    down (sampled piecewise linearly), constant speed between. Returns (points, end time)."""
    v = math.copysign(vmax, distance)
    cruise = abs(distance) / vmax - ramp   # each raised-cosine ramp covers v·ramp/2
    assert cruise > 0, (distance, vmax, ramp)
    up = [(t0 + ramp * k / RAMP_POINTS, v * 0.5 * (1 - math.cos(math.pi * k / RAMP_POINTS))) for k in range(RAMP_POINTS + 1)]
    t2 = t0 + ramp + cruise
    down = [(t2 + ramp * k / RAMP_POINTS, v * 0.5 * (1 + math.cos(math.pi * k / RAMP_POINTS))) for k in range(RAMP_POINTS + 1)]
    return up + down, t2 + ramp


def fmt_hist(points, axis):
    times = ", ".join(f"{t:.9e}" for t, _ in points)
    vals = []
    for _, v in points:
        vec = [0.0, 0.0, 0.0]
        vec[axis] = v
        vals.append("[" + ", ".join(f"{c:.6e}" for c in vec) + "]")
    return f"{{ times = [{times}], values = [{', '.join(vals)}] }}"


def merge(z_pts, x_pts):
    """Normal (z) and tangential (x) velocity histories on one time base."""
    times = sorted(set([p[0] for p in z_pts] + [p[0] for p in x_pts]))

    def at(pts, tt):
        if tt <= pts[0][0]:
            return pts[0][1]
        for (t0, v0), (t1, v1) in zip(pts, pts[1:]):
            if t0 <= tt <= t1:
                return v0 + (v1 - v0) * (tt - t0) / (t1 - t0) if t1 > t0 else v1
        return pts[-1][1]
    ts = ", ".join(f"{tt:.9e}" for tt in times)
    vs = ", ".join(f"[{at(x_pts, tt):.6e}, 0.0, {at(z_pts, tt):.6e}]" for tt in times)
    return f"{{ times = [{ts}], values = [{vs}] }}"


def hertz_scene(p):
    v_plate, ramp, delta_end = p["v_plate"], p["ramp"], p["delta_end"]
    # the plates start `gap` away from the poles and are at full speed before they touch
    # (no acceleration of the mass-scaled contact zone during the loading)
    gap = p["gap"] if p["gap"] > 0 else 0.0
    if ramp > 0:
        up = [(ramp * k / RAMP_POINTS, v_plate * 0.5 * (1 - math.cos(math.pi * k / RAMP_POINTS))) for k in range(RAMP_POINTS + 1)]
        travel_ramp = 0.5 * v_plate * ramp
    else:
        up, travel_ramp = [(0.0, v_plate)], 0.0
    duration = ramp + (gap + delta_end - travel_ramp) / v_plate
    motion = (f"raised-cosine ramp to {v_plate} m/s over {ramp*1e6:.1f} µs, then constant" if ramp > 0
              else f"constant {v_plate} m/s from t = 0")
    damping = f"\n# damps vibration relative to the sphere's rigid motion\ndeformation_damping = {p['damping']:.3e}" if p["damping"] > 0 else ""
    refine = "\n".join(
        f"    {{ direction = [0.0, 0.0, {d}], seeding = 1.0e-5, radius = {p['refine_radius']:.4e}, growth = {p['growth']} }},"
        for d in ("1.0", "-1.0"))
    return f'''# Hertz normal contact: a glass sphere squeezed between two rigid frictionless plates
# (THEORY.md §1, finite-sphere reference). Both plates approach the centre plane at the
# same speed ({motion}), starting {gap*1e6:.2f} µm from the poles, so
# δ = approach of each plate from first touch and F = plate force.
#
# How to run:  mufe validate hertz            (sweep of meshing ratios, plots, JSON)
#              mufe run jobs/validation/hertz.toml --out out/hertz   (one run)
# Generated by scripts/gen_validation_scenes.py (edit there). Meshing: fine seeding only
# around the two poles (refine[0], refine[1]); `mufe validate` sets their seeding from the
# meshing ratio at the contact, MR = s/(2R).

[simulation]
duration = {duration:.6e}
# mass scaling of the fine contact elements only; quasi-static (KE/IE is reported)
target_dt = {p['target_dt']:.3e}{damping}

[materials.glass]
youngs_modulus = {E:e}
poisson_ratio = {NU}
density = {RHO}

[[grains]]
name = "sphere"
material = "glass"
centre = [0.0, 0.0, 0.0]
shape = {{ sphere = {{ radius = {R:e}, seeding = {p['seeding']:.4e}, refine = [
{refine}
] }} }}

[contact]
friction = 0.0

[[walls]]
name = "top"
point = [0.0, 0.0, {R + gap:.9e}]
normal = [0.0, 0.0, -1.0]
velocity = {fmt_hist([(t, -v) for t, v in up], 2)}

[[walls]]
name = "bottom"
point = [0.0, 0.0, {-R - gap:.9e}]
normal = [0.0, 0.0, 1.0]
velocity = {fmt_hist(up, 2)}

[output]
history_interval = {p['history_interval']:.3e}
frames = false
'''


def two_sphere_scene(name, header, p, case_lines, duration):
    return f'''# {header}
#
# How to run:  mufe validate {name}          (sweep of meshing ratios, plots, JSON)
#              mufe run jobs/validation/{name}.toml --out out/{name}
# Generated by scripts/gen_validation_scenes.py (edit there). Normal force target
# N = {p['force']} N (contact radius {contact_radius(p['force'])*1e6:.1f} µm); the reference uses the N
# measured at the fixed base. `mufe validate` sets the seeding of refine[0] from the
# meshing ratio at the contact, MR = s/(2R).

[simulation]
duration = {duration:.6e}
# mass scaling of the fine contact elements only
target_dt = {p['target_dt']:.3e}
# damps vibration of each sphere relative to its rigid-body motion (no net force on it)
deformation_damping = {p['damping']:.3e}

[materials.glass]
youngs_modulus = {E:e}
poisson_ratio = {NU}
density = {RHO}

[contact]
friction = {MU}

[[grains]]
name = "lower"
material = "glass"
centre = [0.0, 0.0, {-R:e}]
shape = {{ sphere = {{ radius = {R:e}, seeding = {p['seeding']:.4e}, refine = [
    {{ direction = [0.0, 0.0, 1.0], seeding = 1.0e-5, radius = {p['refine_radius']:.4e}, growth = {p['growth']} }},
] }} }}

[[grains]]
name = "upper"
material = "glass"
centre = [0.0, 0.0, {R:e}]
shape = {{ sphere = {{ radius = {R:e}, seeding = {p['seeding']:.4e}, refine = [
    {{ direction = [0.0, 0.0, -1.0], seeding = 1.0e-5, radius = {p['refine_radius']:.4e}, growth = {p['growth']} }},
] }} }}

[[boundaries]]
name = "base"
grain = "lower"
select = {{ beyond_plane = {{ point = [0.0, 0.0, {-p['clamp']*R:e}], normal = [0.0, 0.0, -1.0] }} }}
# moments of the base reaction are taken about the lower sphere's centre
centre = [0.0, 0.0, {-R:e}]

{case_lines}

[output]
history_interval = {p['history_interval']:.3e}
frames = false
'''


def normal_phase(p):
    # approach_scale: the held parts at ±clamp·R make the pair stiffer than two Hertz
    # half-spaces; the scale brings the measured N close to `force`
    normal, t = trapezoid(0.0, -p["approach_scale"] * approach_pair(p["force"]), p["vn"], p["n_ramp"])
    return normal, t + p["settle"]


def drive_block(p, velocity, angular=None):
    lines = f'''[[boundaries]]
name = "drive"
grain = "upper"
select = {{ beyond_plane = {{ point = [0.0, 0.0, {p['clamp']*R:e}], normal = [0.0, 0.0, 1.0] }} }}
centre = [0.0, 0.0, {R:e}]
velocity = {velocity}'''
    if angular:
        lines += f"\nangular_velocity = {angular}"
    return lines


def mindlin(p):
    force = p["force"]
    a = contact_radius(force)
    dtmax = 3 * MU * force * (2 - NU) / (8 * G * a)
    normal, t = normal_phase(p)
    amp = p["amplitude"] * dtmax
    seg, t = trapezoid(t, amp, p["vt"], p["t_ramp"])
    tangential = [(0.0, 0.0)] + seg
    for k in range(p["reversals"]):
        seg, t = trapezoid(t, (-2 if k % 2 == 0 else 2) * amp, p["vt"], p["t_ramp"])
        tangential += seg[1:]
    what = ["", ", unloading", ", unloading, reloading"][min(p["reversals"], 2)]
    text = two_sphere_scene("mindlin", f"Mindlin–Deresiewicz: two glass spheres, tangential loading at constant N{what} (THEORY.md §2)",
                            p, drive_block(p, merge(normal, tangential)), t + 0.2e-6)
    return text


def torsion(p):
    force = p["force"]
    a = contact_radius(force)
    normal, t = normal_phase(p)
    # relative twist 2β at G a² β/(μN) = twist_param
    twist = 2.0 * p["twist_param"] * MU * force / (G * a * a)
    w_max = twist / (p["cruise"] + p["t_ramp"])
    seg, t_end = trapezoid(t, twist, w_max, p["t_ramp"])
    return two_sphere_scene("torsion", "Torsion about the contact normal of two glass spheres vs Lubkin's exact curve (THEORY.md §3)",
                            p, drive_block(p, fmt_hist(normal, 2), fmt_hist([(0.0, 0.0)] + seg, 2)), t_end + 0.2e-6)


def rolling(p):
    force = p["force"]
    a = contact_radius(force)
    dtmax = 3 * MU * force * (2 - NU) / (8 * G * a)
    normal, t = normal_phase(p)
    theta_max = p["amplitude"] * dtmax / R
    w_max = theta_max / (p["cruise"] + p["t_ramp"])
    seg, t_end = trapezoid(t, theta_max, w_max, p["t_ramp"])
    return two_sphere_scene("rolling", "Rolling: upper glass sphere rotated about its own fixed centre, moment vs angle (THEORY.md §4)",
                            p, drive_block(p, fmt_hist(normal, 2), fmt_hist([(0.0, 0.0)] + seg, 0)), t_end + 0.2e-6)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).resolve().parent.parent / "jobs" / "validation"))
    ap.add_argument("--set", action="append", default=[], metavar="CASE.KEY=VALUE")
    args = ap.parse_args()
    for item in args.set:
        key, value = item.split("=", 1)
        case, field = key.split(".", 1)
        old = PARAMS[case][field]
        PARAMS[case][field] = type(old)(float(value))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    texts = {"hertz": hertz_scene(PARAMS["hertz"]), "mindlin": mindlin(PARAMS["mindlin"]),
             "torsion": torsion(PARAMS["torsion"]), "rolling": rolling(PARAMS["rolling"])}
    for name, text in texts.items():
        (out / f"{name}.toml").write_text(text)
    print("wrote", *(out / f"{n}.toml" for n in texts))


if __name__ == "__main__":
    main()
