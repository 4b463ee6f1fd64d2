//! `results.xdmf`: an XDMF 3 description of `results.h5` (a temporal collection of
//! unstructured tetrahedral grids, one per frame) so that ParaView or VisIt open the mesh
//! and every frame as a time series. It holds no data: every array is a reference into
//! `results.h5`. Rewritten after every frame, so a run that is stopped still has a valid
//! description of what it wrote.
//!
//! The mesh is the reference configuration; apply ParaView's "Warp By Vector" with
//! `displacement` to see the deformed grains. The stress is stored in `results.h5` as
//! (xx, yy, zz, yz, xz, xy), which is not XDMF's Tensor6 order (xx, xy, xz, yy, yz, zz),
//! so it is described as six scalar components (`stress_xx`, …) taken by hyperslab.
//! `owner_rank` is the MPI rank that advanced each element at that frame; `contact_force`
//! the grain–grain contact force on each (surface) node.

use std::fmt::Write as _;
use std::path::Path;

/// File name of the description, beside `results.h5`.
pub const XDMF_FILE_NAME: &str = "results.xdmf";

/// Sizes of the mesh in `results.h5` and the frames written so far.
pub struct XdmfLayout<'a> {
    /// Name of the HDF5 file as the XDMF file refers to it (same directory).
    pub h5_name: &'a str,
    pub nodes: u64,
    pub elements: u64,
    /// (frame index, time in s) of every frame written.
    pub frames: &'a [(usize, f64)],
}

/// Components of the stored stress, in storage order.
const STRESS_COMPONENTS: [&str; 6] = ["xx", "yy", "zz", "yz", "xz", "xy"];

/// The XDMF text for `layout`.
pub fn xdmf_text(layout: &XdmfLayout) -> String {
    let (n, e, h5) = (layout.nodes, layout.elements, layout.h5_name);
    let mut s = String::from(
        "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n  <Grid Name=\"mufe\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
    );
    for &(index, time) in layout.frames {
        let frame = format!("/frames/{index:06}");
        let _ = writeln!(
            s,
            "   <Grid Name=\"frame_{index:06}\" GridType=\"Uniform\">"
        );
        let _ = writeln!(s, "    <Time Value=\"{time:e}\"/>");
        let _ = writeln!(
            s,
            "    <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"{e}\">\n{}    </Topology>",
            hdf_item(&format!("{e} 4"), "UInt", 8, h5, "/mesh/tetrahedra", 5)
        );
        let _ = writeln!(
            s,
            "    <Geometry GeometryType=\"XYZ\">\n{}    </Geometry>",
            hdf_item(&format!("{n} 3"), "Float", 8, h5, "/mesh/nodes", 5)
        );
        for (name, kind) in [
            ("displacement", "Vector"),
            ("velocity", "Vector"),
            ("contact_force", "Vector"),
        ] {
            attribute(
                &mut s,
                name,
                kind,
                "Node",
                &hdf_item(
                    &format!("{n} 3"),
                    "Float",
                    8,
                    h5,
                    &format!("{frame}/{name}"),
                    5,
                ),
            );
        }
        for (c, component) in STRESS_COMPONENTS.iter().enumerate() {
            let slab = format!(
                "     <DataItem ItemType=\"HyperSlab\" Dimensions=\"{e} 1\">\n      <DataItem Dimensions=\"3 2\" NumberType=\"UInt\" Format=\"XML\">0 {c} 1 1 {e} 1</DataItem>\n{}     </DataItem>\n",
                hdf_item(&format!("{e} 6"), "Float", 8, h5, &format!("{frame}/stress"), 6)
            );
            attribute(
                &mut s,
                &format!("stress_{component}"),
                "Scalar",
                "Cell",
                &slab,
            );
        }
        for name in [
            "von_mises_stress",
            "equivalent_plastic_strain",
            "owner_rank",
        ] {
            attribute(
                &mut s,
                name,
                "Scalar",
                "Cell",
                &hdf_item(
                    &e.to_string(),
                    "Float",
                    8,
                    h5,
                    &format!("{frame}/{name}"),
                    5,
                ),
            );
        }
        attribute(
            &mut s,
            "grain",
            "Scalar",
            "Cell",
            &hdf_item(&e.to_string(), "UInt", 4, h5, "/mesh/grain_of_element", 5),
        );
        s.push_str("   </Grid>\n");
    }
    s.push_str("  </Grid>\n </Domain>\n</Xdmf>\n");
    s
}

/// Writes [`xdmf_text`] to `path` through a temporary file and a rename, so a reader
/// never sees a half-written description.
pub fn write_xdmf(path: &Path, layout: &XdmfLayout) -> std::io::Result<()> {
    let tmp = path.with_extension("xdmf.tmp");
    std::fs::write(&tmp, xdmf_text(layout))?;
    std::fs::rename(&tmp, path)
}

fn hdf_item(dims: &str, kind: &str, precision: u32, h5: &str, path: &str, indent: usize) -> String {
    format!(
        "{:indent$}<DataItem Dimensions=\"{dims}\" NumberType=\"{kind}\" Precision=\"{precision}\" Format=\"HDF\">{h5}:{path}</DataItem>\n",
        ""
    )
}

fn attribute(s: &mut String, name: &str, kind: &str, centre: &str, item: &str) {
    let _ = write!(
        s,
        "    <Attribute Name=\"{name}\" AttributeType=\"{kind}\" Center=\"{centre}\">\n{item}    </Attribute>\n"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_grid_per_frame_with_every_field() {
        let text = xdmf_text(&XdmfLayout {
            h5_name: "results.h5",
            nodes: 10,
            elements: 7,
            frames: &[(0, 0.0), (1, 2.5e-6)],
        });
        assert_eq!(text.matches("<Grid Name=\"frame_").count(), 2);
        assert!(text.contains("<Time Value=\"2.5e-6\"/>"));
        assert!(text.contains("results.h5:/frames/000001/displacement"));
        assert!(text.contains("Name=\"stress_xy\""));
        assert!(
            text.contains("0 5 1 1 7 1"),
            "hyperslab of the 6th stress component"
        );
        // per frame: 3 node vectors, 6 stress components, 3 element scalars, grain id
        assert_eq!(text.matches("<Attribute").count(), 2 * 13);
        assert!(text.trim_end().ends_with("</Xdmf>"));
    }
}
