//! `mufe sand --box`: the virtual sand in a closed box of six walls, packed and then
//! compressed, with frames for ParaView (the shape demo of `jobs/shapes/`). Five stages:
//! 1. *deposit*: under [`DEPOSIT_G`] g, damped, the grains fall into the gaps of the
//!    grains below and settle onto each other and the floor, while the top wall follows
//!    them down, slower than they fall, to the height a packing of the loosest solid
//!    fraction [`LOOSE_FRACTION`] would fill;
//! 2. *lower* (1 g from here on): the top wall at the grains' landing speed until it first
//!    touches the packing;
//! 3. *approach*: the top wall at [`PACK_SPEED`] until it has carried [`TOUCH_FRACTION`]
//!    of the packing load for [`TOUCH_HOLD`] (an impact's spike does not end it);
//! 4. *consolidate*: the top wall servo-held at [`PACK_STRESS`], damped, until the stress
//!    has held;
//! 5. *compress*: the top wall at a constant strain rate, undamped, by [`END_STRAIN`],
//!    the side walls held (oedometric).
//!
//! The start: each grain lies on its flat side (its shortest axis vertical, as flat grains
//! settle) turned by a random azimuth (the surface shape's `rotation`, from the sand's
//! seed), on the sites of a square grid in a checkerboard: sublayer k uses the sites of
//! parity k, so two grains at one height are a diagonal apart, √2 × the pitch = the widest
//! grain's horizontal reach twice plus a gap, whatever their azimuths, while each grain
//! overlaps its four neighbours of the sublayers above and below when seen from above. The
//! grains therefore interlock like bricks as they land instead of stacking in columns (a
//! demo that stacked them in columns before session 16 had the tallest column carry the
//! whole wall load). Each pair of sublayers is shifted by half a pitch from the pair below
//! ([`LAYER_SHIFTS`]), so no grain lands straight on the one two sublayers down.
//!
//! Why a heavy, damped deposit: under 1 g all grains fall together and only the floor
//! stops them, a 15 µm fall takes 1.7 ms, and the grains bounce back (restitution ≈ 0.85
//! at the default contact damping); under [`DEPOSIT_G`] g in a damping of
//! [`DEPOSIT_DAMPING`] they sink at the terminal speed g/c and a rebound dies within 1/c.
//! (Pushing loose grains with the top wall alone leaves them flying, and heavy damping
//! turns a push into drag, m·c·v per grain; a servo-driven wall closes a free gap only at
//! F*/(kτ), hence the wall lowered at constant speed until it touches.)

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::scene::write_grain_stl;
use super::SandParams;

/// Gap between grains at the start, and between grains and walls (× size).
const GAP: f64 = 0.005;
/// Gravity of the deposit (in g = 9.81 m/s²) and its mass damping (1/s): terminal speed
/// g/c = 0.78 m/s.
pub const DEPOSIT_G: f64 = 200.0;
const DEPOSIT_DAMPING: f64 = 2.5e3;
/// How far each sublayer sinks into the one below as the grains interlock (× its
/// height): the deposit lasts long enough for the top grains to fall that far per
/// sublayer.
const NESTING: f64 = 0.5;
/// Offsets of successive pairs of sublayers (in half pitches along x and y), in turn.
const LAYER_SHIFTS: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]];
/// A lower bound of the solid fraction the deposit reaches (–): the top wall follows the
/// deposit down to the height that fraction fills.
const LOOSE_FRACTION: f64 = 0.3;
/// The top wall follows the deposit at most this part of the grains' terminal speed (–),
/// so that the falling grains draw away from it.
const WALL_FOLLOW: f64 = 0.5;
/// The force that counts as the top wall's first touch (× the packing load, –).
const FIRST_TOUCH: f64 = 1.0e-3;
/// Speed of the top wall in the approach (m/s).
const PACK_SPEED: f64 = 0.1;
/// Stress the top wall's servo holds in the consolidation and the compression starts
/// from (Pa) …
pub const PACK_STRESS: f64 = 1.0e5;
/// … and the part of it whose force ends the approach (–): the wall then presses on the
/// packing and the servo takes over.
const TOUCH_FRACTION: f64 = 0.1;
/// How long the approach's force must last (s): an impact's spike lasts a few
/// microseconds.
const TOUCH_HOLD: f64 = 1.0e-5;
/// Mass-proportional damping of the lowering and the approach (1/s): light, or the grains
/// the wall pushes drag through it (a drag m·c·v per grain) instead of loading the floor.
const APPROACH_DAMPING: f64 = 2.0e3;
/// Mass-proportional damping c of the consolidation (1/s) …
const PACK_DAMPING: f64 = 2.0e4;
/// … its servo tolerance (–), its loop time constant in periods of the packing's rigid
/// mode on the servo's Hertz stiffness (the docs' setting for a packing: a loose bed of
/// a few contacts per grain is far softer than the Hertz columns the estimate assumes,
/// and the default 2 periods left 20 % of the stress to go after 40 damping times) and
/// its longest duration in damping times 1/c (–).
const PACK_TOLERANCE: f64 = 0.05;
const PACK_SERVO_PERIODS: f64 = 0.5;
const PACK_MAX_DAMPING_TIMES: f64 = 40.0;
/// Axial strain rate of the compress stage (1/s) and its strain (–).
const STRAIN_RATE: f64 = 5.0;
pub const END_STRAIN: f64 = 1.0e-3;

/// Deterministic rotation of grain `i` about the vertical (axis-angle vector, rad).
fn orientation(seed: u64, i: usize) -> [f64; 3] {
    let mut x = seed
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add((i as u64 + 1).wrapping_mul(0xbf58_476d_1ce4_e5b9));
    let mut unit = || {
        x ^= x >> 31;
        x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
        x ^= x >> 29;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    [0.0, 0.0, 2.0 * std::f64::consts::PI * unit()]
}

/// Grid site (a, b) and sublayer of each of `n` grains: sublayer k takes the sites of an
/// `per_row` × `per_row` grid with a + b ≡ k (mod 2).
fn checkerboard_sites(n: usize, per_row: usize) -> Vec<(usize, usize, usize)> {
    let mut sites = Vec::with_capacity(n);
    let mut k = 0;
    while sites.len() < n {
        for b in 0..per_row {
            for a in 0..per_row {
                if (a + b) % 2 == k % 2 && sites.len() < n {
                    sites.push((a, b, k));
                }
            }
        }
        k += 1;
    }
    sites
}

/// Writes the grains and `scene.toml` (box, stages, frames) into `dir`; returns the scene.
pub fn write_sand_box(dir: &Path, p: &SandParams) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let n = p.grains;
    let per_row = ((n as f64).cbrt().ceil() as usize).max(2);
    let gap = GAP * p.size;
    // the turn about the vertical changes neither a point's horizontal distance from the
    // centroid nor its height
    let (mut reach, mut half_height) = (0.0_f64, 0.0_f64);
    let mut rotations = Vec::with_capacity(n);
    for i in 0..n {
        let (s, _) = write_grain_stl(dir, p, i)?;
        for q in &s.points {
            reach = reach.max(q[0].hypot(q[1]));
            half_height = half_height.max(q[2].abs());
        }
        rotations.push(orientation(p.seed, i));
    }
    let pitch = (2.0 * reach + gap) / std::f64::consts::SQRT_2;
    let rise = 2.0 * half_height + gap;
    let sites = checkerboard_sites(n, per_row);
    let sublayers = sites.last().map_or(1, |s| s.2 + 1);
    let width = 2.0 * (reach + gap) + (per_row as f64 - 0.5) * pitch;
    let span = [width, width, sublayers as f64 * rise + gap];
    let pack_area = width * width;
    let pack_force = PACK_STRESS * pack_area;
    let touch_force = TOUCH_FRACTION * pack_force;
    let c_p = (7.0e10_f64 / 2650.0).sqrt();
    // mass scaling to a step of a third of the regular tet at the seeding
    let target_dt = 0.3 * 0.565 * p.seeding / c_p;
    // the top grains fall the meshes' chord sag (≲ s²/(4 r_eq) twice) and the nesting of
    // every sublayer below them: at the terminal speed, then four damping times to rest
    let g_deposit = DEPOSIT_G * 9.81;
    let terminal_speed = g_deposit / DEPOSIT_DAMPING;
    let fall = (sublayers - 1) as f64 * NESTING * rise + gap + p.seeding * p.seeding / p.size;
    // the loosest packing's height (never below one sublayer): where the top wall waits
    let solid = n as f64 * std::f64::consts::PI / 6.0 * p.size.powi(3);
    let loose_height = (solid / (LOOSE_FRACTION * pack_area))
        .max(rise + gap)
        .min(span[2]);
    let wall_drop = span[2] - loose_height;
    let deposit_time = (fall / terminal_speed + 4.0 / DEPOSIT_DAMPING)
        .max(wall_drop / (WALL_FOLLOW * terminal_speed));
    let follow_speed = wall_drop / deposit_time;
    // the lowering may go down to one sublayer, the approach by one more grain height
    let lower_time = (loose_height - rise).max(gap) / terminal_speed;
    let approach_time = rise / PACK_SPEED;
    let consolidate_time = PACK_MAX_DAMPING_TIMES / PACK_DAMPING;
    let compress_time = 1.5 * END_STRAIN / STRAIN_RATE;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Virtual sand in a box, written by `mufe sand --box --grains {n} --seed {} --elongation {} --flatness {} --roughness {} --size {:e} --seeding {:e}`\n\
         # (src/sand/box_scene.rs; docs/SHAPES.md, \"Demo\"). {n} grains of equivalent diameter {:.3} mm, lying flat at random\n\
         # azimuths, start in {sublayers} checkerboard sublayers of a {per_row}×{per_row} grid in a box of six frictional walls\n\
         # ({:.3} × {:.3} × {:.3} mm). Stages: deposit ({DEPOSIT_G} g, damped, {:.3} ms; the top wall follows down to {:.3} mm);\n\
         # lower (1 g from here on; the top wall at {:.3} m/s until it touches); approach (the top wall at {PACK_SPEED} m/s\n\
         # until it carries {:.4} N); consolidate (the top wall servo-held at {:.0} kPa, damped, until held); compress\n\
         # (the top wall at {STRAIN_RATE} 1/s, undamped, by {:.1} % more).\n\
         #   mpirun -n 2 mufe run jobs/shapes/scene.toml --out out/shapes    (frames: out/shapes/results.xdmf)",
        p.seed,
        p.elongation,
        p.flatness,
        p.roughness,
        p.size,
        p.seeding,
        p.size * 1e3,
        span[0] * 1e3,
        span[1] * 1e3,
        span[2] * 1e3,
        deposit_time * 1e3,
        loose_height * 1e3,
        terminal_speed,
        touch_force,
        PACK_STRESS / 1e3,
        100.0 * END_STRAIN
    );
    let _ = writeln!(
        t,
        "\n[simulation]\nduration = {:.6e}   # s: a cap; the stages end the run\ngravity = [0.0, 0.0, -9.81]   # m/s²\ntarget_dt = {target_dt:.3e}   # s: mass scaling of the slivers (reported by mufe check)\n",
        deposit_time + lower_time + approach_time + consolidate_time + compress_time
    );
    let _ = writeln!(
        t,
        "[materials.quartz]\nyoungs_modulus = 7.0e10   # Pa\npoisson_ratio = 0.17\ndensity = 2650.0   # kg/m³\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.3\n");
    for (i, (w, &(a, b, k))) in rotations.iter().zip(&sites).enumerate() {
        let shift = LAYER_SHIFTS[(k / 2) % LAYER_SHIFTS.len()];
        let c = [
            reach + gap + (a as f64 + 0.5 * shift[0]) * pitch,
            reach + gap + (b as f64 + 0.5 * shift[1]) * pitch,
            gap + half_height + k as f64 * rise,
        ];
        let _ = writeln!(
            t,
            "[[grains]]\nname = \"g{i}\"\nmaterial = \"quartz\"\ncentre = [{:.6e}, {:.6e}, {:.6e}]\nshape = {{ surface = {{ file = \"grain_{i:03}.stl\", units = \"mm\", seeding = {:e}, rotation = [{:.6}, {:.6}, {:.6}] }} }}\n",
            c[0], c[1], c[2], p.seeding, w[0], w[1], w[2]
        );
    }
    let wall = |t: &mut String, name: &str, point: [f64; 3], normal: [f64; 3]| {
        let _ = writeln!(
            t,
            "[[walls]]\nname = \"{name}\"\npoint = [{:.6e}, {:.6e}, {:.6e}]\nnormal = [{:.1}, {:.1}, {:.1}]\nfriction = 0.3\n",
            point[0], point[1], point[2], normal[0], normal[1], normal[2]
        );
    };
    wall(&mut t, "x_min", [0.0; 3], [1.0, 0.0, 0.0]);
    wall(&mut t, "x_max", [span[0], 0.0, 0.0], [-1.0, 0.0, 0.0]);
    wall(&mut t, "y_min", [0.0; 3], [0.0, 1.0, 0.0]);
    wall(&mut t, "y_max", [0.0, span[1], 0.0], [0.0, -1.0, 0.0]);
    wall(&mut t, "bottom", [0.0; 3], [0.0, 0.0, 1.0]);
    wall(&mut t, "top", [0.0, 0.0, span[2]], [0.0, 0.0, -1.0]);
    let _ = writeln!(
        t,
        "[[stages]]\nname = \"deposit\"\ndamping = {DEPOSIT_DAMPING:e}   # 1/s (ALLVD)\n\
         walls = {{ top = {{ velocity = {follow_speed:.6e} }} }}   # m/s: down to {loose_height:.6e} m\n\
         gravity = [0.0, 0.0, {:.6e}]   # m/s²: {DEPOSIT_G} g\n\
         until = {{ max_time = {deposit_time:.6e} }}   # s\n\n\
         [[stages]]\nname = \"lower\"\ndamping = {APPROACH_DAMPING:e}   # 1/s\n\
         walls = {{ top = {{ velocity = {terminal_speed:.6e} }} }}   # m/s: the grains' landing speed\n\
         until = {{ wall_force = {{ wall = \"top\", force = {:.6e} }}, max_time = {lower_time:.6e} }}   # N, s\n\n\
         [[stages]]\nname = \"approach\"\ndamping = {APPROACH_DAMPING:e}   # 1/s\n\
         walls = {{ top = {{ velocity = {PACK_SPEED:e} }} }}   # m/s\n\
         until = {{ wall_force = {{ wall = \"top\", force = {touch_force:.6e}, hold = {TOUCH_HOLD:e} }}, max_time = {approach_time:.6e} }}   # N, s\n\n\
         [[stages]]\nname = \"consolidate\"\ndamping = {PACK_DAMPING:e}   # 1/s\n\
         walls = {{ top = {{ servo = {{ stress = {PACK_STRESS:e}, area = {pack_area:.6e}, periods = {PACK_SERVO_PERIODS} }} }} }}   # Pa, m²\n\
         until = {{ stress_held = {{ tolerance = {PACK_TOLERANCE} }}, max_time = {consolidate_time:.6e} }}   # s\n\n\
         [[stages]]\nname = \"compress\"\ndamping = 0.0\n\
         walls = {{ top = {{ strain_rate = {STRAIN_RATE:e} }} }}   # 1/s\n\
         until = {{ axial_strain = {END_STRAIN:e}, max_time = {compress_time:.6e} }}\n\n\
         [output]\nhistory_interval = 1.0e-6   # s\nframe_interval = {:.3e}   # s\n",
        -g_deposit,
        FIRST_TOUCH * pack_force,
        2.0e-5
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, t)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checkerboard_sublayers_alternate_parity_and_hold_every_grain() {
        let sites = checkerboard_sites(27, 3);
        assert_eq!(sites.len(), 27);
        // 5 even and 4 odd sites of a 3 × 3 grid, in turn: 6 sublayers
        assert_eq!(sites.last().unwrap().2, 5);
        for &(a, b, k) in &sites {
            assert_eq!((a + b) % 2, k % 2);
        }
        // two grains of one sublayer are at least a diagonal (√2 pitches) apart
        for (i, s) in sites.iter().enumerate() {
            for t in &sites[i + 1..] {
                if s.2 == t.2 {
                    let d2 = (s.0 as i64 - t.0 as i64).pow(2) + (s.1 as i64 - t.1 as i64).pow(2);
                    assert!(d2 >= 2, "{s:?} {t:?}");
                }
            }
        }
    }
}
