//! `mufe sand --box`: the virtual sand in a closed box of six walls, with four stages —
//! *deposit* (under [`DEPOSIT_G`] g, damped, every wall held: the grains settle onto
//! each other and the floor), *approach* (1 g from here on; the top wall at a constant
//! speed until it has carried [`PACK_STRESS`] for [`PACK_HOLD`]: the bottom wall's force
//! still remembers the deposit's weight, and impacts spike), *settle* (every wall held,
//! heavily damped, for [`SETTLE_DAMPING_TIMES`] damping times: the assembly comes to rest
//! on its own contacts under that load) and *compress* (the top wall at a constant strain
//! rate, undamped, by [`END_STRAIN`]) — and frames for ParaView. The shape demo of
//! `jobs/shapes/` is this output.
//!
//! Each grain lies on its flat side (its shortest axis vertical, as flat grains settle)
//! turned by a random azimuth (the surface shape's `rotation`, from the sand's seed), in a
//! column of a grid whose spacing is the largest horizontal extent of any turned grain
//! plus a small gap [`GAP`], each grain that gap above the one below it (or the floor).
//! Why a heavy, damped deposit: under 1 g all grains fall together and only the floor
//! stops them, a 15 µm fall takes 1.7 ms, and the grains bounce back (restitution ≈ 0.85
//! at the default contact damping); under [`DEPOSIT_G`] g in a damping of
//! [`DEPOSIT_DAMPING`] they sink at the terminal speed g/c and a rebound dies within 1/c.
//! (Pushing loose grains with the top wall alone leaves them flying — kinetic energy 40×
//! the strain energy at the end of a 0.5 m/s push — and heavy damping turns a push into
//! drag, m·c·v per grain; a servo-driven wall approaches a free gap only at F*/(kτ).)

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::scene::write_grain_stl;
use super::SandParams;
use crate::mesh::import::{bounding_box, rotate};

/// Gap between the cells of the start grid, between the grains of a column and between
/// grains and walls (× size).
const GAP: f64 = 0.005;
/// Gravity of the deposit (in g = 9.81 m/s²) and its mass damping (1/s): terminal speed
/// g/c = 0.2 m/s.
pub const DEPOSIT_G: f64 = 100.0;
const DEPOSIT_DAMPING: f64 = 5.0e3;
/// Speed of the top wall in the approach (m/s).
const PACK_SPEED: f64 = 0.1;
/// Stress on the top wall that ends the approach (Pa) …
pub const PACK_STRESS: f64 = 1.0e5;
/// … once it has carried it for this long (s): an impact's spike lasts a few
/// microseconds. The wall moves on meanwhile, by speed × hold = 1 µm: on columns of stiff
/// grains that overshoots the stress (≈ 2×, measured).
const PACK_HOLD: f64 = 1.0e-5;
/// Longest approach, as axial strain of the top wall (–).
const PACK_MAX_STRAIN: f64 = 0.1;
/// Mass-proportional damping of the approach (1/s): light, or the grains the wall pushes
/// drag through it (a drag m·c·v per grain) instead of loading the floor.
const APPROACH_DAMPING: f64 = 2.0e3;
/// Mass-proportional damping c of the settling stage (1/s).
const PACK_DAMPING: f64 = 2.0e4;
/// Length of the settling stage in damping times 1/c (–): the kinetic energy of a freely
/// moving mass falls as e^(−2ct).
pub const SETTLE_DAMPING_TIMES: f64 = 8.0;
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

/// Writes the grains and `scene.toml` (box, stages, frames) into `dir`; returns the scene.
pub fn write_sand_box(dir: &Path, p: &SandParams) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let n = p.grains;
    let per_row = (n as f64).cbrt().ceil() as usize;
    let mut extent = [0.0_f64; 3];
    let mut rotations = Vec::with_capacity(n);
    let gap = GAP * p.size;
    // columns: each grain a gap above the one below it (or the floor)
    let mut column_top = vec![0.0_f64; per_row * per_row];
    let mut heights_z = Vec::with_capacity(n);
    for i in 0..n {
        let (s, _) = write_grain_stl(dir, p, i)?;
        let w = orientation(p.seed, i);
        let mut turned = s.points;
        rotate(&mut turned, w);
        let (lo, hi) = bounding_box(&turned);
        for k in 0..3 {
            // the centroid is the origin: the cell must hold the farther side twice
            extent[k] = extent[k].max(2.0 * (-lo[k]).max(hi[k]));
        }
        rotations.push(w);
        let top = &mut column_top[i % (per_row * per_row)];
        let z = *top + gap - lo[2];
        *top = z + hi[2];
        heights_z.push(z);
    }
    let cell = extent.map(|e| e + gap);
    let layers = n.div_ceil(per_row * per_row);
    let span = [
        per_row as f64 * cell[0],
        per_row as f64 * cell[1],
        column_top.iter().fold(0.0_f64, |m, &z| m.max(z)) + gap,
    ];
    let pack_force = PACK_STRESS * span[0] * span[1];
    let c_p = (7.0e10_f64 / 2650.0).sqrt();
    // mass scaling to a step of a third of the regular tet at the seeding
    let target_dt = 0.3 * 0.565 * p.seeding / c_p;
    let pack_time = PACK_MAX_STRAIN * span[2] / PACK_SPEED;
    let compress_time = 1.5 * END_STRAIN / STRAIN_RATE;
    let settle_time = SETTLE_DAMPING_TIMES / PACK_DAMPING;
    // each layer may fall its gap plus the chord sag of its meshed surface (≲ s²/(4 r_eq)
    // twice): at the terminal speed, then four damping times to come to rest
    let g_deposit = DEPOSIT_G * 9.81;
    let fall = layers as f64 * (gap + p.seeding * p.seeding / p.size);
    let deposit_time = fall / (g_deposit / DEPOSIT_DAMPING) + 4.0 / DEPOSIT_DAMPING;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Virtual sand in a box, written by `mufe sand --box --grains {n} --seed {} --elongation {} --flatness {} --roughness {} --size {:e} --seeding {:e}`\n\
         # (src/sand/box_scene.rs; docs/SHAPES.md, \"Demo\"). {n} grains of equivalent diameter {:.3} mm, lying\n\
         # flat at random azimuths, start on a {per_row}×{per_row}×{layers} grid in a box of six frictional walls ({:.3} × {:.3} × {:.3} mm).\n\
         # Stage deposit: {DEPOSIT_G} g, damped, every wall held, for {:.3} ms; stage approach (1 g from here on): the top wall\n\
         # at {PACK_SPEED} m/s until it carries {:.0} kPa ({:.4} N); stage settle: every wall held, damped, for\n\
         # {SETTLE_DAMPING_TIMES} damping times; stage compress: the top wall at {STRAIN_RATE} 1/s, undamped, by {:.1} % more.\n\
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
        PACK_STRESS / 1e3,
        pack_force,
        100.0 * END_STRAIN
    );
    let _ = writeln!(
        t,
        "\n[simulation]\nduration = {:.6e}   # s: a cap; the stages end the run\ngravity = [0.0, 0.0, -9.81]   # m/s²\ntarget_dt = {target_dt:.3e}   # s: mass scaling of the slivers (reported by mufe check)\n",
        deposit_time + pack_time + settle_time + compress_time
    );
    let _ = writeln!(
        t,
        "[materials.quartz]\nyoungs_modulus = 7.0e10   # Pa\npoisson_ratio = 0.17\ndensity = 2650.0   # kg/m³\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.3\n");
    for (i, w) in rotations.iter().enumerate() {
        let (a, b) = (i % per_row, (i / per_row) % per_row);
        let c = [
            (a as f64 + 0.5) * cell[0],
            (b as f64 + 0.5) * cell[1],
            heights_z[i],
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
         gravity = [0.0, 0.0, {:.6e}]   # m/s²: {DEPOSIT_G} g\n\
         until = {{ max_time = {deposit_time:.6e} }}   # s\n\n\
         [[stages]]\nname = \"approach\"\ndamping = {APPROACH_DAMPING:e}   # 1/s\n\
         walls = {{ top = {{ velocity = {PACK_SPEED:e} }} }}   # m/s\n\
         until = {{ wall_force = {{ wall = \"top\", force = {pack_force:.6e}, hold = {PACK_HOLD:e} }}, max_time = {pack_time:.6e} }}   # N, s\n\n\
         [[stages]]\nname = \"settle\"\ndamping = {PACK_DAMPING:e}   # 1/s: {SETTLE_DAMPING_TIMES} damping times, every wall held\n\
         until = {{ max_time = {settle_time:.6e} }}   # s\n\n\
         [[stages]]\nname = \"compress\"\ndamping = 0.0\n\
         walls = {{ top = {{ strain_rate = {STRAIN_RATE:e} }} }}   # 1/s\n\
         until = {{ axial_strain = {END_STRAIN:e}, max_time = {compress_time:.6e} }}\n\n\
         [output]\nhistory_interval = 1.0e-6   # s\nframe_interval = {:.3e}   # s\n",
        -g_deposit,
        2.0e-5
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, t)?;
    Ok(path)
}
