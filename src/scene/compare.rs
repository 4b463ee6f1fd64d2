//! Comparing two scenes for a restart: a checkpoint continues only the scene it was
//! written for, up to output settings and the end time, which a user may change between
//! the pieces of a long run.

/// The first difference between scene texts `a` and `b` (a dotted path with both values),
/// ignoring `[output]` and `simulation.duration`; `None` when they describe the same run.
/// A text that is not TOML differs as a whole.
pub fn first_difference(a: &str, b: &str) -> Option<String> {
    let parse = |t: &str| t.parse::<toml::Table>().ok().map(without_run_settings);
    match (parse(a), parse(b)) {
        (Some(a), Some(b)) => differ("", &toml::Value::Table(a), &toml::Value::Table(b)),
        _ => Some("the scene text".to_string()),
    }
}

fn without_run_settings(mut t: toml::Table) -> toml::Table {
    t.remove("output");
    if let Some(toml::Value::Table(sim)) = t.get_mut("simulation") {
        sim.remove("duration");
    }
    t
}

fn differ(path: &str, a: &toml::Value, b: &toml::Value) -> Option<String> {
    let at = |key: &str| {
        if path.is_empty() {
            key.to_string()
        } else {
            format!("{path}.{key}")
        }
    };
    match (a, b) {
        (toml::Value::Table(x), toml::Value::Table(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| match (x.get(k), y.get(k)) {
                (Some(u), Some(v)) => differ(&at(k), u, v),
                (Some(u), None) => Some(format!("{} = {u} in the checkpoint, absent here", at(k))),
                (None, Some(v)) => Some(format!("{} absent in the checkpoint, {v} here", at(k))),
                (None, None) => None,
            })
        }
        (toml::Value::Array(x), toml::Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| differ(&format!("{path}[{i}]"), u, v)),
        _ if a == b => None,
        _ => Some(format!("{path} = {a} in the checkpoint, {b} here")),
    }
}

#[cfg(test)]
mod tests {
    use super::first_difference;

    #[test]
    fn output_and_duration_may_change_physics_may_not() {
        let a =
            "[simulation]\nduration = 1e-3\n[output]\nframes = true\n[material]\nfriction = 0.3\n";
        let b = "[simulation]\nduration = 5e-3\n[material]\nfriction = 0.3\n";
        assert_eq!(first_difference(a, b), None);
        let c = "[simulation]\nduration = 5e-3\n[material]\nfriction = 0.5\n";
        let d = first_difference(a, c).expect("friction differs");
        assert!(d.starts_with("material.friction = 0.3"), "{d}");
        let e = "[simulation]\nduration = 1e-3\n[[grains]]\nr = 1\n[[grains]]\nr = 2\n";
        let f = "[simulation]\nduration = 1e-3\n[[grains]]\nr = 1\n[[grains]]\nr = 3\n";
        assert!(first_difference(e, f).unwrap().starts_with("grains[1].r"));
    }
}
