//! The crate's modules depend one way (docs/ARCHITECTURE.md §1): no import cycle between
//! source files or between top-level modules, and the lower layers never reach up.
//! Reads every `crate::…`/`super::…` path in `src/` (up to a file's `#[cfg(test)]`
//! module, where tests may use any layer; a unit-test module in a file of its own is
//! skipped whole) and resolves it to the file that defines it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The files of unit-test modules declared on their own (`#[cfg(test)] mod tests;`): test
/// code, which may use any layer, like an inline `#[cfg(test)]` module.
fn unit_test_files(files: &[PathBuf]) -> BTreeSet<PathBuf> {
    let mut out = BTreeSet::new();
    for f in files {
        let text = std::fs::read_to_string(f).unwrap();
        // a `mod.rs` or `lib.rs` holds its submodules beside it, `x.rs` in `x/`
        let dir = match f.file_stem().and_then(|s| s.to_str()) {
            Some("mod" | "lib") => f.parent().unwrap().to_path_buf(),
            _ => f.with_extension(""),
        };
        for after in text.split("#[cfg(test)]").skip(1) {
            let Some(name) = after
                .trim_start()
                .strip_prefix("mod ")
                .and_then(|rest| rest.split_once(';'))
                .map(|(name, _)| name.trim())
                .filter(|name| name.chars().all(|c| c.is_alphanumeric() || c == '_'))
            else {
                continue;
            };
            out.insert(dir.join(format!("{name}.rs")));
            out.insert(dir.join(name).join("mod.rs"));
        }
    }
    out
}

/// Module path of a file relative to `src` (`solver/step.rs` → [solver, step]).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// The longest existing module file for a path.
fn file_for(src: &Path, parts: &[String]) -> Option<PathBuf> {
    (1..=parts.len()).rev().find_map(|k| {
        let base: PathBuf = parts[..k].iter().fold(src.to_path_buf(), |p, s| p.join(s));
        [base.with_extension("rs"), base.join("mod.rs")]
            .into_iter()
            .find(|c| c.is_file())
    })
}

/// Source without comments, up to the unit-test module.
fn code_of(file: &Path) -> String {
    let text = std::fs::read_to_string(file).unwrap();
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::a::b` / `super::a` path of a file, as module paths; `use x::{a, b::c}`
/// groups are expanded one level.
fn referenced_paths(text: &str, module: &[String]) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for root in ["crate::", "super::"] {
        let mut from = 0;
        while let Some(i) = text[from..].find(root) {
            let start = from + i;
            from = start + root.len();
            if start > 0 {
                let prev = text[..start].chars().last().unwrap();
                if prev.is_alphanumeric() || prev == '_' {
                    continue;
                }
            }
            let rest = &text[from..];
            let path_len = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(rest.len());
            let path = rest[..path_len].trim_end_matches(':');
            let mut parts: Vec<String> = path
                .split("::")
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect();
            if root == "super::" {
                let parent = &module[..module.len().saturating_sub(1)];
                parts = parent.iter().cloned().chain(parts).collect();
            }
            let after = &rest[path_len..];
            if after.starts_with('{') {
                let group = &after[1..after.find('}').unwrap_or(after.len())];
                for item in group.split(',') {
                    let head = item.trim().split("::").next().unwrap_or("").trim();
                    if !head.is_empty() && head != "self" {
                        out.push(parts.iter().cloned().chain([head.to_string()]).collect());
                    }
                }
            }
            out.push(parts);
        }
    }
    out
}

struct Graph {
    files: BTreeMap<PathBuf, BTreeSet<PathBuf>>,
    modules: BTreeMap<String, BTreeSet<String>>,
}

fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let unit_tests = unit_test_files(&files);
    files.retain(|f| !unit_tests.contains(f));
    let mut g = Graph {
        files: BTreeMap::new(),
        modules: BTreeMap::new(),
    };
    for f in &files {
        let module = module_of(&src, f);
        let top = module.first().cloned().unwrap_or_default();
        for parts in referenced_paths(&code_of(f), &module) {
            let Some(target) = file_for(&src, &parts) else {
                continue;
            };
            if target != *f {
                g.files.entry(f.clone()).or_default().insert(target);
            }
            let to = parts.first().cloned().unwrap_or_default();
            let is_module = src.join(&to).is_dir() || src.join(format!("{to}.rs")).is_file();
            if !top.is_empty() && to != top && is_module {
                g.modules.entry(top.clone()).or_default().insert(to);
            }
        }
    }
    g
}

/// Strongly connected components with more than one member (Tarjan).
fn cycles<T: Ord + Clone>(edges: &BTreeMap<T, BTreeSet<T>>) -> Vec<Vec<T>> {
    struct Tarjan<'a, T: Ord> {
        edges: &'a BTreeMap<T, BTreeSet<T>>,
        index: BTreeMap<T, usize>,
        low: BTreeMap<T, usize>,
        stack: Vec<T>,
        on: BTreeSet<T>,
        out: Vec<Vec<T>>,
    }
    impl<T: Ord + Clone> Tarjan<'_, T> {
        fn visit(&mut self, v: &T) {
            let i = self.index.len();
            self.index.insert(v.clone(), i);
            self.low.insert(v.clone(), i);
            self.stack.push(v.clone());
            self.on.insert(v.clone());
            for w in self.edges.get(v).into_iter().flatten() {
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if self.on.contains(w) {
                    let iw = self.index[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut comp = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on.remove(&w);
                    let done = w == *v;
                    comp.push(w);
                    if done {
                        break;
                    }
                }
                if comp.len() > 1 {
                    self.out.push(comp);
                }
            }
        }
    }
    let mut t = Tarjan {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in edges.keys() {
        if !t.index.contains_key(v) {
            t.visit(v);
        }
    }
    t.out
}

#[test]
fn no_import_cycle_between_files() {
    let c = cycles(&graph().files);
    assert!(c.is_empty(), "file import cycles: {c:#?}");
}

#[test]
fn no_import_cycle_between_modules() {
    let g = graph();
    let c = cycles(&g.modules);
    assert!(
        c.is_empty(),
        "module import cycles: {c:#?}\nedges: {:#?}",
        g.modules
    );
}

#[test]
fn lower_layers_never_reach_up() {
    let g = graph();
    // module → modules it must not use (docs/ARCHITECTURE.md §1)
    let forbidden: [(&str, &[&str]); 7] = [
        (
            "kinematics",
            &[
                "model", "contact", "solver", "driver", "domain", "io", "validate", "cli",
            ],
        ),
        (
            "model",
            &[
                "contact", "solver", "driver", "domain", "io", "validate", "cli",
            ],
        ),
        (
            "contact",
            &["solver", "driver", "domain", "io", "validate", "cli"],
        ),
        ("solver", &["driver", "domain", "io", "validate", "cli"]),
        (
            "domain",
            &["contact", "solver", "driver", "io", "validate", "cli"],
        ),
        ("io", &["contact", "solver", "driver", "validate", "cli"]),
        ("driver", &["validate", "cli"]),
    ];
    let mut bad = Vec::new();
    for (from, never) in forbidden {
        for to in g.modules.get(from).into_iter().flatten() {
            if never.contains(&to.as_str()) {
                bad.push(format!("{from} → {to}"));
            }
        }
    }
    assert!(bad.is_empty(), "layer violations: {bad:?}");
    // the check sees real edges (a parser that finds nothing would pass vacuously)
    assert!(g.modules["solver"].contains("contact") && g.modules["contact"].contains("model"));
}
