//! Readers and writers of surface files: STL (binary and ASCII, through `stl_io`),
//! Wavefront OBJ (through `tobj`; polygons fan-triangulated) and Gmsh MSH 4.1 ASCII (own
//! parser: surface triangles, or a tetrahedral volume mesh used as is). Crate choices:
//! docs/SHAPES.md.
//!
//! Every surface reader returns the same canonical [`Surface`]: vertices with bit-identical
//! coordinates merged, numbered in order of first appearance in the facet list, unused
//! vertices dropped. So one surface written in any of the formats reads back identically
//! (given coordinates exact in f32, STL's precision), and meshes identically.

use std::collections::HashMap;
use std::io::Write;

use super::Surface;
use crate::mesh::TetMesh;

/// What a file holds: a triangulated surface, or (MSH only) a ready tetrahedral mesh.
#[derive(Debug, Clone, PartialEq)]
pub enum Imported {
    Surface(Surface),
    Volume(TetMesh),
}

/// A read failure: the item (`line 12`, `file`) and what is wrong; the caller adds the file.
pub type ReadError = (String, String);

/// The surface formats, by file extension (case-insensitive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Stl,
    Obj,
    Msh,
}

impl Format {
    pub fn from_path(path: &std::path::Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "stl" => Some(Format::Stl),
            "obj" => Some(Format::Obj),
            "msh" => Some(Format::Msh),
            _ => None,
        }
    }
}

/// Parses the bytes of a surface file of the given format.
pub fn read(format: Format, bytes: &[u8]) -> Result<Imported, ReadError> {
    match format {
        Format::Stl => read_stl(bytes).map(Imported::Surface),
        Format::Obj => read_obj(bytes).map(Imported::Surface),
        Format::Msh => read_msh(bytes),
    }
}

/// Merges bit-identical vertices of a triangle soup (−0 and +0 are the same point).
pub fn surface_from_soup(triangles: impl IntoIterator<Item = [[f64; 3]; 3]>) -> Surface {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut s = Surface::default();
    for tri in triangles {
        let facet = tri.map(|p| {
            let key = p.map(|c| (c + 0.0).to_bits());
            *index.entry(key).or_insert_with(|| {
                s.points.push(p);
                (s.points.len() - 1) as u32
            })
        });
        s.facets.push(facet);
    }
    s
}

fn soup_of(points: &[[f64; 3]], facets: &[[u32; 3]]) -> Surface {
    surface_from_soup(facets.iter().map(|f| f.map(|i| points[i as usize])))
}

fn read_stl(bytes: &[u8]) -> Result<Surface, ReadError> {
    // A binary STL whose 80-byte header happens to start with "solid" is common (some CAD
    // exporters write it); stl_io then tries ASCII. The size of a binary file is exact
    // (84 + 50 n bytes), so such a file has its header neutralised first.
    let mut data = bytes.to_vec();
    if data.len() >= 84 && data.starts_with(b"solid") {
        let n = u32::from_le_bytes([data[80], data[81], data[82], data[83]]) as usize;
        if data.len() == 84 + 50 * n {
            data[..5].copy_from_slice(b"SOLID");
        }
    }
    let mut cursor = std::io::Cursor::new(data);
    let reader = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| ("file".to_string(), format!("not an STL file: {e}")))?;
    let mut soup = Vec::new();
    for (i, t) in reader.enumerate() {
        let t = t.map_err(|e| (format!("facet {i}"), format!("cannot read the facet: {e}")))?;
        soup.push(t.vertices.map(|v| v.0.map(f64::from)));
    }
    if soup.is_empty() {
        return Err(("file".into(), "the STL file has no facets".into()));
    }
    Ok(surface_from_soup(soup))
}

fn read_obj(bytes: &[u8]) -> Result<Surface, ReadError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| ("file".to_string(), format!("not a readable OBJ file: {e}")))?;
    let mut soup = Vec::new();
    for m in &models {
        let p = &m.mesh.positions;
        let point = |i: u32| {
            let i = 3 * i as usize;
            [p[i], p[i + 1], p[i + 2]]
        };
        for f in m.mesh.indices.chunks_exact(3) {
            soup.push([point(f[0]), point(f[1]), point(f[2])]);
        }
    }
    if soup.is_empty() {
        return Err(("file".into(), "the OBJ file has no faces".into()));
    }
    Ok(surface_from_soup(soup))
}

/// Gmsh element types read: 3-node triangle and 4-node tetrahedron.
const MSH_TRIANGLE: usize = 2;
const MSH_TETRAHEDRON: usize = 4;

/// The MSH 4.1 ASCII subset: `$MeshFormat`, `$Nodes`, `$Elements` (other sections are
/// skipped; element types other than triangles and tets are ignored). With any tets the
/// file is a volume mesh (its triangles ignored), else a surface.
fn read_msh(bytes: &[u8]) -> Result<Imported, ReadError> {
    let text = std::str::from_utf8(bytes).map_err(|_| {
        (
            "file".to_string(),
            "not a text file (binary MSH is not read; save as ASCII 4.1)".to_string(),
        )
    })?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let mut next = |what: &str| -> Result<(usize, &str), ReadError> {
        lines
            .next()
            .ok_or_else(|| ("file".to_string(), format!("ends early, expected {what}")))
    };
    let (mut version_ok, mut nodes, mut tag_index) = (false, Vec::new(), HashMap::new());
    let (mut triangles, mut tets) = (Vec::<[u32; 3]>::new(), Vec::<[u32; 4]>::new());
    while let Ok((ln, line)) = next("a section") {
        match line {
            "" => continue,
            "$MeshFormat" => {
                let (ln, l) = next("the format line")?;
                let mut it = l.split_whitespace();
                let (v, ty) = (it.next(), it.next());
                if v != Some("4.1") || ty != Some("0") {
                    return Err((
                        format!("line {ln}"),
                        format!("MSH version/type '{l}' is not read; only 4.1 ASCII ('4.1 0 8')"),
                    ));
                }
                version_ok = true;
            }
            "$Nodes" => {
                let (ln, l) = next("the $Nodes header")?;
                let h = numbers::<usize>(ln, l, 4)?;
                for _ in 0..h[0] {
                    let (ln, l) = next("a node block header")?;
                    let b = numbers::<usize>(ln, l, 4)?;
                    if b[2] != 0 {
                        return Err((format!("line {ln}"), "parametric nodes are not read".into()));
                    }
                    // the count is read from the file: it bounds nothing until the tags
                    // are there (a damaged header must end in "ends early", not an abort)
                    let mut tags = Vec::with_capacity(b[3].min(text.len()));
                    for _ in 0..b[3] {
                        let (ln, l) = next("a node tag")?;
                        tags.push(numbers::<usize>(ln, l, 1)?[0]);
                    }
                    for tag in tags {
                        let (ln, l) = next("node coordinates")?;
                        let x = numbers::<f64>(ln, l, 3)?;
                        if x.iter().any(|c| !c.is_finite()) {
                            return Err((format!("line {ln}"), "non-finite coordinate".into()));
                        }
                        tag_index.insert(tag, nodes.len() as u32);
                        nodes.push([x[0], x[1], x[2]]);
                    }
                }
            }
            "$Elements" => {
                let (ln, l) = next("the $Elements header")?;
                let h = numbers::<usize>(ln, l, 4)?;
                for _ in 0..h[0] {
                    let (ln, l) = next("an element block header")?;
                    let b = numbers::<usize>(ln, l, 4)?;
                    for _ in 0..b[3] {
                        let (ln, l) = next("an element")?;
                        let node = |tag: usize| {
                            tag_index.get(&tag).copied().ok_or_else(|| {
                                (
                                    format!("line {ln}"),
                                    format!("element refers to node {tag}, which is not defined"),
                                )
                            })
                        };
                        match b[2] {
                            MSH_TRIANGLE => {
                                let e = numbers::<usize>(ln, l, 4)?;
                                triangles.push([node(e[1])?, node(e[2])?, node(e[3])?]);
                            }
                            MSH_TETRAHEDRON => {
                                let e = numbers::<usize>(ln, l, 5)?;
                                tets.push([node(e[1])?, node(e[2])?, node(e[3])?, node(e[4])?]);
                            }
                            _ => {}
                        }
                    }
                }
            }
            other if other.starts_with('$') && !other.starts_with("$End") => {
                // A section we do not need ($Entities, $PhysicalNames, …): skip to its end.
                let end = format!("$End{}", &other[1..]);
                while next(&end)?.1 != end {}
            }
            other if other.starts_with("$End") => {}
            other => {
                return Err((
                    format!("line {ln}"),
                    format!(
                        "unexpected '{}' outside a section",
                        crate::error::echo(other)
                    ),
                ))
            }
        }
    }
    if !version_ok {
        return Err((
            "file".into(),
            "no $MeshFormat section: not a Gmsh MSH file".into(),
        ));
    }
    if !tets.is_empty() {
        let mut mesh = TetMesh { nodes, tets };
        for t in mesh.tets.iter_mut() {
            if crate::mesh::tet_volume(&t.map(|i| mesh.nodes[i as usize])) < 0.0 {
                t.swap(2, 3);
            }
        }
        return Ok(Imported::Volume(mesh));
    }
    if triangles.is_empty() {
        return Err((
            "file".into(),
            "the MSH file has neither triangles nor tetrahedra".into(),
        ));
    }
    Ok(Imported::Surface(soup_of(&nodes, &triangles)))
}

/// The first `n` whitespace-separated numbers of a line.
fn numbers<T: std::str::FromStr>(ln: usize, line: &str, n: usize) -> Result<Vec<T>, ReadError> {
    let v: Vec<T> = line
        .split_whitespace()
        .take(n)
        .map(|w| w.parse::<T>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            (
                format!("line {ln}"),
                format!("expected {n} numbers, got '{}'", crate::error::echo(line)),
            )
        })?;
    if v.len() < n {
        return Err((
            format!("line {ln}"),
            format!("expected {n} numbers, got '{}'", crate::error::echo(line)),
        ));
    }
    Ok(v)
}

/// Writes a binary STL (coordinates rounded to f32, as the format stores them).
pub fn write_stl_binary(s: &Surface, out: &mut impl Write) -> std::io::Result<()> {
    let tris: Vec<stl_io::Triangle> = s
        .facets
        .iter()
        .map(|f| {
            let x = f.map(|i| s.points[i as usize]);
            let n = crate::math::cross(crate::math::sub(x[1], x[0]), crate::math::sub(x[2], x[0]));
            let l = crate::math::norm(n).max(f64::MIN_POSITIVE);
            stl_io::Triangle {
                normal: stl_io::Normal::new(n.map(|c| (c / l) as f32)),
                vertices: x.map(|p| stl_io::Vertex::new(p.map(|c| c as f32))),
            }
        })
        .collect();
    stl_io::write_stl(out, tris.iter())
}

/// Writes an ASCII STL (f32 coordinates, printed exactly).
pub fn write_stl_ascii(s: &Surface, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "solid mufe")?;
    for f in &s.facets {
        writeln!(out, "facet normal 0 0 0\n  outer loop")?;
        for &i in f {
            let p = s.points[i as usize].map(|c| c as f32);
            writeln!(out, "    vertex {:e} {:e} {:e}", p[0], p[1], p[2])?;
        }
        writeln!(out, "  endloop\nendfacet")?;
    }
    writeln!(out, "endsolid mufe")
}

/// Writes a Wavefront OBJ (full f64 precision).
pub fn write_obj(s: &Surface, out: &mut impl Write) -> std::io::Result<()> {
    for p in &s.points {
        writeln!(out, "v {:e} {:e} {:e}", p[0], p[1], p[2])?;
    }
    for f in &s.facets {
        writeln!(out, "f {} {} {}", f[0] + 1, f[1] + 1, f[2] + 1)?;
    }
    Ok(())
}

/// Writes a Gmsh MSH 4.1 ASCII surface (one surface entity of triangles).
pub fn write_msh(s: &Surface, out: &mut impl Write) -> std::io::Result<()> {
    write_msh_elements(
        &s.points,
        2,
        MSH_TRIANGLE,
        s.facets.iter().map(|f| f.to_vec()),
        s.facets.len(),
        out,
    )
}

/// Writes a Gmsh MSH 4.1 ASCII tetrahedral volume mesh.
pub fn write_msh_volume(m: &TetMesh, out: &mut impl Write) -> std::io::Result<()> {
    write_msh_elements(
        &m.nodes,
        3,
        MSH_TETRAHEDRON,
        m.tets.iter().map(|t| t.to_vec()),
        m.tets.len(),
        out,
    )
}

fn write_msh_elements(
    points: &[[f64; 3]],
    dim: usize,
    kind: usize,
    elements: impl Iterator<Item = Vec<u32>>,
    count: usize,
    out: &mut impl Write,
) -> std::io::Result<()> {
    let n = points.len();
    writeln!(out, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
    writeln!(out, "$Nodes\n1 {n} 1 {n}\n{dim} 1 0 {n}")?;
    for i in 1..=n {
        writeln!(out, "{i}")?;
    }
    for p in points {
        writeln!(out, "{:e} {:e} {:e}", p[0], p[1], p[2])?;
    }
    writeln!(
        out,
        "$EndNodes\n$Elements\n1 {count} 1 {count}\n{dim} 1 {kind} {count}"
    )?;
    for (k, e) in elements.enumerate() {
        let ids: Vec<String> = e.iter().map(|i| (i + 1).to_string()).collect();
        writeln!(out, "{} {}", k + 1, ids.join(" "))?;
    }
    writeln!(out, "$EndElements")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> Surface {
        let p = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let f = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        soup_of(&p, &f)
    }

    #[test]
    fn every_format_reads_back_the_same_surface() {
        let s = octahedron();
        type Writer = fn(&Surface, &mut Vec<u8>) -> std::io::Result<()>;
        let cases: [(Format, Writer); 4] = [
            (Format::Stl, |s, o| write_stl_binary(s, o)),
            (Format::Stl, |s, o| write_stl_ascii(s, o)),
            (Format::Obj, |s, o| write_obj(s, o)),
            (Format::Msh, |s, o| write_msh(s, o)),
        ];
        for (format, write) in cases {
            let mut bytes = Vec::new();
            write(&s, &mut bytes).unwrap();
            assert_eq!(
                read(format, &bytes).unwrap(),
                Imported::Surface(s.clone()),
                "{format:?}"
            );
        }
    }

    #[test]
    fn binary_stl_with_a_solid_header_is_read_as_binary() {
        let s = octahedron();
        let mut bytes = Vec::new();
        write_stl_binary(&s, &mut bytes).unwrap();
        bytes[..6].copy_from_slice(b"solid ");
        assert_eq!(read(Format::Stl, &bytes).unwrap(), Imported::Surface(s));
    }

    #[test]
    fn obj_polygons_are_fan_triangulated() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let Imported::Surface(s) = read(Format::Obj, text.as_bytes()).unwrap() else {
            panic!()
        };
        assert_eq!(s.facets, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn msh_errors_name_the_line() {
        let e = read(Format::Msh, b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n").unwrap_err();
        assert_eq!(e.0, "line 2");
        let e = read(
            Format::Msh,
            b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 x\n",
        )
        .unwrap_err();
        assert_eq!(e.0, "line 5");
        // a node block that claims more nodes than memory can hold ends early, no abort
        let e = read(
            Format::Msh,
            b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 100000000000000000\n1\n",
        )
        .unwrap_err();
        assert!(e.1.contains("ends early, expected a node tag"), "{e:?}");
        let mut m = Vec::new();
        write_msh_volume(
            &TetMesh {
                nodes: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
                tets: vec![[0, 1, 2, 3]],
            },
            &mut m,
        )
        .unwrap();
        let Imported::Volume(v) = read(Format::Msh, &m).unwrap() else {
            panic!()
        };
        assert!(crate::mesh::tet_volume(&v.tets[0].map(|i| v.nodes[i as usize])) > 0.0);
    }
}
