//! `--set PATH=VALUE`: override any scene field by dotted path before the scene is typed,
//! so overridden values get exactly the validation of values in the file.
//!
//! Paths: `simulation.duration`, `materials.glass.youngs_modulus`, `grains.0.centre`,
//! `grains[0].shape.sphere.radius`. VALUE is a TOML value (`1e-3`, `[0,0,1]`, `"a"`,
//! `true`); a bare word that is not valid TOML is taken as a string.

/// Applies one `PATH=VALUE` override to a TOML table. The error names what is wrong.
pub fn apply_override(root: &mut toml::Value, assignment: &str) -> Result<(), String> {
    let (path, raw) = assignment
        .split_once('=')
        .ok_or_else(|| "expected PATH=VALUE".to_string())?;
    let path = path.trim();
    if path.is_empty() {
        return Err("empty PATH".into());
    }
    let value = parse_value(raw.trim());
    let segments = split_path(path)?;
    let (last, parents) = segments
        .split_last()
        .expect("split_path returns at least one segment");
    let mut node: &mut toml::Value = root;
    let mut walked = String::new();
    for seg in parents {
        node = step_into(node, seg, &walked)?;
        if !walked.is_empty() {
            walked.push('.');
        }
        walked.push_str(seg);
    }
    match node {
        toml::Value::Table(t) => {
            // A field that does not exist yet may be set (optional fields); serde rejects
            // unknown names afterwards with the full path.
            t.insert(last.clone(), value);
            Ok(())
        }
        toml::Value::Array(a) => {
            let i: usize = last
                .parse()
                .map_err(|_| format!("'{walked}' is a list: '{last}' is not an index"))?;
            let n = a.len();
            let slot = a
                .get_mut(i)
                .ok_or_else(|| format!("'{walked}' has {n} {}, no index {i}", entries(n)))?;
            *slot = value;
            Ok(())
        }
        _ => Err(format!("'{walked}' is a value, it has no field '{last}'")),
    }
}

/// Top-level scene tables that have defaults and may be created by `--set`.
const OPTIONAL_SECTIONS: [&str; 3] = ["contact", "output", "parallel"];

fn step_into<'v>(
    node: &'v mut toml::Value,
    seg: &str,
    walked: &str,
) -> Result<&'v mut toml::Value, String> {
    let here = if walked.is_empty() {
        seg.to_string()
    } else {
        format!("{walked}.{seg}")
    };
    match node {
        // Optional top-level sections may be absent from the file: `--set contact.friction=0.3`
        // creates `[contact]` (serde then validates its fields as usual).
        toml::Value::Table(t) => {
            if walked.is_empty() && OPTIONAL_SECTIONS.contains(&seg) && !t.contains_key(seg) {
                t.insert(seg.to_string(), toml::Value::Table(toml::Table::new()));
            }
            t.get_mut(seg)
                .ok_or_else(|| format!("no field '{here}' in the scene"))
        }
        toml::Value::Array(a) => {
            let i: usize = seg
                .parse()
                .map_err(|_| format!("'{walked}' is a list: '{seg}' is not an index"))?;
            let n = a.len();
            a.get_mut(i)
                .ok_or_else(|| format!("'{walked}' has {n} {}, no index {i}", entries(n)))
        }
        _ => Err(format!("'{walked}' is a value, it has no field '{seg}'")),
    }
}

/// Segments of a dotted field path (`grains[0].centre` and `grains.0.centre` give the
/// same), or `None` if it is not one.
pub(super) fn path_segments(path: &str) -> Option<Vec<String>> {
    if path.is_empty() || path.contains(char::is_whitespace) {
        return None;
    }
    split_path(path).ok()
}

/// `a.b[2].c` → ["a", "b", "2", "c"].
fn split_path(path: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let mut rest = part;
        let name_end = rest.find('[').unwrap_or(rest.len());
        let name = &rest[..name_end];
        if !name.is_empty() {
            out.push(name.to_string());
        } else if name_end == rest.len() {
            return Err(format!("empty segment in path '{path}'"));
        }
        rest = &rest[name_end..];
        while let Some(stripped) = rest.strip_prefix('[') {
            let close = stripped
                .find(']')
                .ok_or_else(|| format!("unclosed '[' in path '{path}'"))?;
            out.push(stripped[..close].to_string());
            rest = &stripped[close + 1..];
        }
        if !rest.is_empty() {
            return Err(format!("unexpected '{rest}' in path '{path}'"));
        }
    }
    Ok(out)
}

fn entries(n: usize) -> &'static str {
    if n == 1 {
        "entry"
    } else {
        "entries"
    }
}

fn parse_value(raw: &str) -> toml::Value {
    let doc = format!("v = {raw}");
    match toml::from_str::<toml::Table>(&doc) {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or(toml::Value::String(raw.to_string())),
        Err(_) => toml::Value::String(raw.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(s: &str) -> toml::Value {
        toml::Value::Table(toml::from_str(s).unwrap())
    }

    #[test]
    fn sets_nested_and_indexed_fields() {
        let mut t = table("[a]\nb = 1\n[[g]]\nr = 1.0\n[[g]]\nr = 2.0\n");
        apply_override(&mut t, "a.b=5").unwrap();
        apply_override(&mut t, "g[1].r=3.5").unwrap();
        apply_override(&mut t, "g.0.r=[1,2]").unwrap();
        assert_eq!(t["a"]["b"].as_integer(), Some(5));
        assert_eq!(t["g"][1]["r"].as_float(), Some(3.5));
        assert!(t["g"][0]["r"].is_array());
    }

    #[test]
    fn bad_paths_are_explained() {
        let mut t = table("[a]\nb = 1\n[[g]]\nr = 1.0\n");
        assert!(apply_override(&mut t, "x.y=1")
            .unwrap_err()
            .contains("no field 'x'"));
        assert!(apply_override(&mut t, "g[3].r=1")
            .unwrap_err()
            .contains("no index 3"));
        assert!(apply_override(&mut t, "a.b.c=1")
            .unwrap_err()
            .contains("has no field"));
        assert!(apply_override(&mut t, "novalue")
            .unwrap_err()
            .contains("PATH=VALUE"));
        // the table is intact after a failed override
        assert_eq!(t["a"]["b"].as_integer(), Some(1));
    }
}
