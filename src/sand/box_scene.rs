//! `mufe sand --box`: the virtual sand in a closed box of six walls, with two stages —
//! *pack* (the top wall at a constant speed with mass damping until the bottom wall carries
//! [`PACK_STRESS`]: the grains have been pushed together down to the floor) and *compress* (the top wall at a
//! constant strain rate, undamped, by [`END_STRAIN`]) — and frames for ParaView. The shape
//! demo of `jobs/shapes/` is this output.
//!
//! Each grain lies on its flat side (its shortest axis vertical, as flat grains settle)
//! turned by a random azimuth (the surface shape's `rotation`, from the sand's seed), in a
//! cell of a grid whose spacing per axis is the largest extent of any turned grain along
//! it plus a small gap: the grains start apart, and the pack stage closes the gaps.
//! (A servo-driven wall approaches a free gap only at F*/(kτ), millimetres per second: a
//! first version spent its 2 ms pack stage 8 µm above the grains; a pack to a precomputed
//! strain — the tallest column closed on its grains' extreme points — left the columns
//! open, as irregular grains nest past their extreme points.)

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::scene::write_grain_stl;
use super::SandParams;
use crate::mesh::import::{bounding_box, rotate};

/// Gap between the cells of the start grid and between grains and walls (× size).
const GAP: f64 = 0.02;
/// Speed of the top wall in the pack stage (m/s).
const PACK_SPEED: f64 = 0.5;
/// Stress on the bottom wall that ends the pack stage (Pa).
pub const PACK_STRESS: f64 = 2.0e3;
/// Longest pack stage, as axial strain of the top wall (–).
const PACK_MAX_STRAIN: f64 = 0.3;
/// Axial strain rate of the compress stage (1/s) and its strain (–).
const STRAIN_RATE: f64 = 50.0;
pub const END_STRAIN: f64 = 3.0e-3;

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
    }
    let gap = GAP * p.size;
    let cell = extent.map(|e| e + gap);
    let layers = n.div_ceil(per_row * per_row);
    let span = [
        per_row as f64 * cell[0],
        per_row as f64 * cell[1],
        layers as f64 * cell[2],
    ];
    let pack_force = PACK_STRESS * span[0] * span[1];
    let c_p = (7.0e10_f64 / 2650.0).sqrt();
    // mass scaling to a step of a third of the regular tet at the seeding
    let target_dt = 0.3 * 0.565 * p.seeding / c_p;
    let pack_time = PACK_MAX_STRAIN * span[2] / PACK_SPEED;
    let compress_time = 1.5 * END_STRAIN / STRAIN_RATE;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Virtual sand in a box, written by `mufe sand --box --grains {n} --seed {} --elongation {} --flatness {} --roughness {} --size {:e} --seeding {:e}`\n\
         # (src/sand/box_scene.rs; docs/SHAPES.md, \"Demo\"). {n} grains of equivalent diameter {:.3} mm, lying\n\
         # flat at random azimuths, start on a {per_row}×{per_row}×{layers} grid in a box of six frictional walls ({:.3} × {:.3} × {:.3} mm).\n\
         # Stage pack: the top wall at {PACK_SPEED} m/s with mass damping until the bottom wall carries {:.0} kPa\n\
         # ({:.4} N); stage compress: the top wall at {STRAIN_RATE} 1/s, undamped, by {:.1} % more.\n\
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
        PACK_STRESS / 1e3,
        pack_force,
        100.0 * END_STRAIN
    );
    let _ = writeln!(
        t,
        "\n[simulation]\nduration = {:.6e}   # s: a cap; the stages end the run\ngravity = [0.0, 0.0, -9.81]   # m/s²\ntarget_dt = {target_dt:.3e}   # s: mass scaling of the slivers (reported by mufe check)\n",
        pack_time + compress_time
    );
    let _ = writeln!(
        t,
        "[materials.quartz]\nyoungs_modulus = 7.0e10   # Pa\npoisson_ratio = 0.17\ndensity = 2650.0   # kg/m³\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.3\n");
    for (i, w) in rotations.iter().enumerate() {
        let (a, b, l) = (
            i % per_row,
            (i / per_row) % per_row,
            i / (per_row * per_row),
        );
        let c = [
            (a as f64 + 0.5) * cell[0],
            (b as f64 + 0.5) * cell[1],
            (l as f64 + 0.5) * cell[2],
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
        "[[stages]]\nname = \"pack\"\ndamping = 2.0e4   # 1/s: settles the grains into the pack (ALLVD)\n\
         walls = {{ top = {{ velocity = {PACK_SPEED:e} }} }}   # m/s\n\
         until = {{ wall_force = {{ wall = \"bottom\", force = {pack_force:.6e} }}, max_time = {pack_time:.6e} }}   # N, s\n\n\
         [[stages]]\nname = \"compress\"\ndamping = 0.0\n\
         walls = {{ top = {{ strain_rate = {STRAIN_RATE:e} }} }}   # 1/s\n\
         until = {{ axial_strain = {END_STRAIN:e}, max_time = {compress_time:.6e} }}\n\n\
         [output]\nhistory_interval = 1.0e-6   # s\nframe_interval = {:.3e}   # s\n",
        2.0e-5
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, t)?;
    Ok(path)
}
