//! Writes a virtual sand: one binary STL per grain (in mm) and `scene.toml` placing the
//! grains on a loose grid (centres 1.5 bounding diameters apart) between a bottom and a
//! top wall, under gravity, which `mufe check` accepts as written.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{grain_surface, SandParams};
use crate::math::norm;
use crate::mesh::import::formats::write_stl_binary;

/// Writes the grains and the scene into `dir` (created if needed); returns the scene path.
pub fn write_sand(dir: &Path, p: &SandParams) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let mut names = Vec::with_capacity(p.grains);
    let mut bound: f64 = 0.0;
    for i in 0..p.grains {
        let mut s = grain_surface(p, i);
        bound = bound.max(s.points.iter().map(|x| norm(*x)).fold(0.0, f64::max));
        // Millimetres in the file: sizes of order one, well resolved in f32.
        s.points.iter_mut().for_each(|x| *x = x.map(|c| c * 1e3));
        let name = format!("grain_{i:03}.stl");
        let mut f = std::io::BufWriter::new(std::fs::File::create(dir.join(&name))?);
        write_stl_binary(&s, &mut f)?;
        names.push(name);
    }
    let per_row = (p.grains as f64).sqrt().ceil() as usize;
    let spacing = 3.0 * bound;
    let layer = per_row * per_row;
    let layers = p.grains.div_ceil(layer);
    let top = (layers as f64 - 1.0) * spacing + 2.4 * bound;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Virtual sand written by `mufe sand --grains {} --seed {} --elongation {} --flatness {} --roughness {} --size {:e} --seeding {:e}`",
        p.grains, p.seed, p.elongation, p.flatness, p.roughness, p.size, p.seeding
    );
    let _ = writeln!(
        t,
        "[simulation]\nduration = 2.0e-3\ngravity = [0.0, 0.0, -9.81]\ndeformation_damping = 0.0\n"
    );
    let _ = writeln!(
        t,
        "[materials.quartz]\nyoungs_modulus = 7.0e10\npoisson_ratio = 0.17\ndensity = 2650.0\n"
    );
    let _ = writeln!(t, "[contact]\nfriction = 0.3\n");
    for (i, name) in names.iter().enumerate() {
        let (k, j, l) = (i % per_row, (i / per_row) % per_row, i / layer);
        let c = [
            k as f64 * spacing,
            j as f64 * spacing,
            1.2 * bound + l as f64 * spacing,
        ];
        let _ = writeln!(
            t,
            "[[grains]]\nname = \"g{i}\"\nmaterial = \"quartz\"\ncentre = [{:e}, {:e}, {:e}]\nshape = {{ surface = {{ file = \"{name}\", units = \"mm\", seeding = {:e} }} }}\n",
            c[0], c[1], c[2], p.seeding
        );
    }
    let _ = writeln!(
        t,
        "[[walls]]\nname = \"bottom\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nfriction = 0.3\n"
    );
    let _ = writeln!(
        t,
        "[[walls]]\nname = \"top\"\npoint = [0.0, 0.0, {top:e}]\nnormal = [0.0, 0.0, -1.0]\nfriction = 0.3"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, t)?;
    Ok(path)
}
