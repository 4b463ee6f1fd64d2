//! Fuzz test of the input contract (README "Errors", docs/INPUT.md): a seeded, hand-written
//! generator (xorshift64*) mutates every scene under `jobs/` and
//! `tests/fixtures/valid_small.toml` and builds bad command lines; every case must end
//! with exit 0, or exit 2 and exactly one stderr line `error: FILE: FIELD: what is wrong`,
//! within a time bound, with no panic or signal; refused runs must leave an existing
//! output directory untouched. A few accepted scenes, shrunk below an element budget, run
//! 3 steps and must give finite energies.
//!
//! Mutation classes: deleted field, unknown field, wrong type, wrong array length, extreme
//! or non-finite number, duplicated name, dangling name, overlapping grains, truncated
//! file, binary file, bad command line. `MUFE_FUZZ_SEED` and `MUFE_FUZZ_CASES` change the
//! seed (default 9) and the number of cases (default 600).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const MUFE: &str = env!("CARGO_BIN_EXE_mufe");
/// Per-case wall-time bound.
const CASE_BOUND: Duration = Duration::from_secs(30);

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn base_scenes() -> Vec<PathBuf> {
    let mut out = vec![root().join("tests/fixtures/valid_small.toml")];
    for dir in std::fs::read_dir(root().join("jobs")).unwrap() {
        let dir = dir.unwrap().path();
        if dir.is_dir() {
            for f in std::fs::read_dir(&dir).unwrap() {
                let f = f.unwrap().path();
                if f.extension().is_some_and(|e| e == "toml") {
                    out.push(f);
                }
            }
        }
    }
    out.sort();
    out
}

/// Every path to a value in the tree (tables and arrays included), as segments.
fn paths(v: &toml::Value, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                prefix.push(k.clone());
                out.push(prefix.clone());
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(i.to_string());
                out.push(prefix.clone());
                paths(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn get_mut<'a>(v: &'a mut toml::Value, path: &[String]) -> Option<&'a mut toml::Value> {
    let mut node = v;
    for seg in path {
        node = match node {
            toml::Value::Table(t) => t.get_mut(seg)?,
            toml::Value::Array(a) => a.get_mut(seg.parse::<usize>().ok()?)?,
            _ => return None,
        };
    }
    Some(node)
}

const EXTREMES: [f64; 14] = [
    0.0,
    -0.0,
    -1.0,
    1e300,
    -1e300,
    1e-300,
    -1e-300,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::MAX,
    f64::MIN_POSITIVE,
    5e-324,
    1e20,
];

fn extreme(rng: &mut Rng) -> toml::Value {
    match rng.below(4) {
        0 => toml::Value::Integer(*rng.pick(&[0, -1, i64::MAX, i64::MIN, 1 << 40, 4_000_000_000])),
        _ => toml::Value::Float(*rng.pick(&EXTREMES)),
    }
}

fn wrong_type(rng: &mut Rng) -> toml::Value {
    match rng.below(5) {
        0 => toml::Value::String("fast".into()),
        1 => toml::Value::Boolean(true),
        2 => toml::Value::Array(vec![]),
        3 => toml::Value::Table(toml::Table::new()),
        _ => toml::Value::String("x".repeat(100_000)),
    }
}

/// Names present in the scene (grains, boundaries, walls, materials).
fn names(v: &toml::Value) -> Vec<String> {
    let mut out = Vec::new();
    for list in ["grains", "boundaries", "walls"] {
        if let Some(a) = v.get(list).and_then(|x| x.as_array()) {
            for e in a {
                if let Some(n) = e.get("name").and_then(|n| n.as_str()) {
                    out.push(n.to_string());
                }
            }
        }
    }
    if let Some(t) = v.get("materials").and_then(|m| m.as_table()) {
        out.extend(t.keys().cloned());
    }
    out
}

/// One mutated scene: (class, scene bytes).
fn mutate(rng: &mut Rng, text: &str) -> (&'static str, Vec<u8>) {
    let mut v: toml::Value = toml::Value::Table(toml::from_str(text).unwrap());
    let mut all = Vec::new();
    paths(&v, &mut Vec::new(), &mut all);
    let class = rng.below(10);
    let path = rng.pick(&all).clone();
    let (parent, last) = path.split_at(path.len() - 1);
    let name = match class {
        0 => {
            if let Some(p) = get_mut(&mut v, parent) {
                match p {
                    toml::Value::Table(t) => {
                        t.remove(&last[0]);
                    }
                    toml::Value::Array(a) => {
                        a.remove(last[0].parse::<usize>().unwrap());
                    }
                    _ => {}
                }
            }
            "deleted field"
        }
        1 => {
            if let Some(toml::Value::Table(t)) = get_mut(&mut v, parent) {
                t.insert("colour".into(), toml::Value::String("red".into()));
            } else if let toml::Value::Table(t) = &mut v {
                t.insert("extra".into(), toml::Value::Integer(1));
            }
            "unknown field"
        }
        2 => {
            let w = wrong_type(rng);
            if let Some(x) = get_mut(&mut v, &path) {
                *x = w;
            }
            "wrong type"
        }
        3 => {
            // wrong length: grow or shrink the nearest array
            let target = all
                .iter()
                .filter(|p| matches!(get_mut(&mut v.clone(), p), Some(toml::Value::Array(_))))
                .cloned()
                .collect::<Vec<_>>();
            if !target.is_empty() {
                let p = rng.pick(&target).clone();
                let grow = rng.below(2) == 0;
                if let Some(toml::Value::Array(a)) = get_mut(&mut v, &p) {
                    if grow || a.is_empty() {
                        a.push(toml::Value::Float(0.0));
                    } else {
                        a.pop();
                    }
                }
            }
            "wrong length"
        }
        4..=5 => {
            // an extreme number at a numeric leaf
            let nums: Vec<Vec<String>> = all
                .iter()
                .filter(|p| {
                    matches!(
                        get_mut(&mut v.clone(), p),
                        Some(toml::Value::Float(_) | toml::Value::Integer(_))
                    )
                })
                .cloned()
                .collect();
            let e = extreme(rng);
            if !nums.is_empty() {
                let p = rng.pick(&nums).clone();
                if let Some(x) = get_mut(&mut v, &p) {
                    *x = e;
                }
            }
            "extreme number"
        }
        6 => {
            let known = names(&v);
            let nm: Vec<Vec<String>> = all
                .iter()
                .filter(|p| p.last().is_some_and(|s| s == "name"))
                .cloned()
                .collect();
            if !nm.is_empty() && !known.is_empty() {
                let dup = rng.pick(&known).clone();
                let p = rng.pick(&nm).clone();
                if let Some(x) = get_mut(&mut v, &p) {
                    *x = toml::Value::String(dup);
                }
            }
            "duplicated name"
        }
        7 => {
            let refs: Vec<Vec<String>> = all
                .iter()
                .filter(|p| p.last().is_some_and(|s| s == "material" || s == "grain"))
                .cloned()
                .collect();
            if !refs.is_empty() {
                let p = rng.pick(&refs).clone();
                if let Some(x) = get_mut(&mut v, &p) {
                    *x = toml::Value::String("nowhere".into());
                }
            }
            "dangling name"
        }
        8 => {
            // overlapping grains: a grain moved onto another (or next to it)
            let n = v
                .get("grains")
                .and_then(|g| g.as_array())
                .map_or(0, Vec::len);
            if n >= 1 {
                let a = rng.below(n);
                let centre = v["grains"][a]
                    .get("centre")
                    .cloned()
                    .unwrap_or(toml::Value::Array(vec![0.0.into(), 0.0.into(), 0.0.into()]));
                let mut copy = v["grains"][a].clone();
                if let Some(t) = copy.as_table_mut() {
                    t.insert("name".into(), toml::Value::String("overlapper".into()));
                    let mut c = centre;
                    if rng.below(2) == 0 {
                        if let Some(x) = c.as_array_mut().and_then(|c| c.get_mut(0)) {
                            let x0 = x.as_float().unwrap_or(0.0);
                            *x = toml::Value::Float(x0 + 1e-9);
                        }
                    }
                    t.insert("centre".into(), c);
                }
                v["grains"].as_array_mut().unwrap().push(copy);
            }
            "overlapping grains"
        }
        _ => {
            let s = toml::to_string(&v).unwrap();
            return if rng.below(2) == 0 {
                let cut = rng.below(s.len().max(1));
                ("truncated file", s.as_bytes()[..cut].to_vec())
            } else {
                let mut bytes = s.into_bytes();
                let n = bytes.len().min(4096);
                for b in bytes.iter_mut().take(n) {
                    if rng.below(8) == 0 {
                        *b = rng.next() as u8;
                    }
                }
                ("binary file", bytes)
            };
        }
    };
    (name, toml::to_string(&v).unwrap_or_default().into_bytes())
}

/// A bad (or odd) command line for a valid scene.
fn bad_command_line(rng: &mut Rng, scene: &str, out: &str) -> Vec<String> {
    let s = |x: &str| x.to_string();
    let options: Vec<Vec<String>> = vec![
        vec![s("check"), s(scene), s("--set"), s("simulation.duration")],
        vec![
            s("check"),
            s(scene),
            s("--set"),
            s("simulation.duration=1e-8\nx=1"),
        ],
        vec![
            s("check"),
            s(scene),
            s("--set"),
            s("simulation.duration=\u{7}"),
        ],
        vec![s("check"), s(scene), s("--set"), s("nosuch.field=1")],
        vec![
            s("check"),
            s(scene),
            s("--set"),
            s("grains[99].centre=[0,0,0]"),
        ],
        vec![s("check"), s(scene), s("--set"), s("=1")],
        vec![
            s("check"),
            s(scene),
            s("--set"),
            format!("simulation.duration={}", "9".repeat(5000)),
        ],
        vec![s("check"), s(scene), s("--bogus")],
        vec![s("check")],
        vec![s("check"), s("/no/such/scene.toml")],
        vec![
            s("run"),
            s(scene),
            s("--threads"),
            s("0"),
            s("--out"),
            s(out),
        ],
        vec![
            s("run"),
            s(scene),
            s("--threads"),
            s("-3"),
            s("--out"),
            s(out),
        ],
        vec![
            s("run"),
            s(scene),
            s("--max-steps"),
            s("x"),
            s("--out"),
            s(out),
        ],
        vec![s("run"), s(scene), s("--out"), s(scene)],
        vec![s("partition"), s(scene), s("--parts"), s("0")],
        vec![
            s("partition"),
            s(scene),
            s("--parts"),
            s("1"),
            s("--margin"),
            s("nan"),
        ],
        vec![s("validate"), s("nosuchcase")],
        vec![s("validate"), s("hertz"), s("--mr"), s("a,b")],
        vec![s("frobnicate")],
        vec![],
    ];
    rng.pick(&options).clone()
}

struct Case {
    id: usize,
    class: &'static str,
    args: Vec<String>,
    /// Output directory with a sentinel file, for `run` cases.
    out: Option<PathBuf>,
}

/// Runs one case under the time bound; returns (exit code, stdout, stderr, wall time).
fn run_case(args: &[String]) -> Result<(Option<i32>, String, String, Duration), String> {
    let t0 = Instant::now();
    let mut child = Command::new(MUFE)
        .args(args)
        .env("MUFE_MEMORY_LIMIT", "128M")
        .env_remove("MUFE_VALIDATION_SCENES")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("OMPI_MCA_hwloc_base_binding_policy", "none")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    let mut out_pipe = child.stdout.take().unwrap();
    let mut err_pipe = child.stderr.take().unwrap();
    let so = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = out_pipe.read_to_end(&mut s);
        s
    });
    let se = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = err_pipe.read_to_end(&mut s);
        s
    });
    loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            let out = String::from_utf8_lossy(&so.join().unwrap()).into_owned();
            let err = String::from_utf8_lossy(&se.join().unwrap()).into_owned();
            #[cfg(unix)]
            if let Some(sig) = std::os::unix::process::ExitStatusExt::signal(&status) {
                return Err(format!("killed by signal {sig}; stderr: {err}"));
            }
            return Ok((status.code(), out, err, t0.elapsed()));
        }
        if t0.elapsed() > CASE_BOUND {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("no answer within {CASE_BOUND:?}"));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn check_case(case: &Case) -> Result<Duration, String> {
    let (code, stdout, stderr, took) = run_case(&case.args)?;
    match code {
        Some(0) => {
            if case.args.first().is_some_and(|c| c == "check") && !stdout.contains("ok: ") {
                return Err(format!("exit 0 without 'ok:': {stdout}"));
            }
        }
        Some(2) => {
            let lines: Vec<&str> = stderr.lines().collect();
            if lines.len() != 1 || !stderr.ends_with('\n') {
                return Err(format!(
                    "exit 2 with {} stderr lines: {stderr:?}",
                    lines.len()
                ));
            }
            let parts: Vec<&str> = lines[0].splitn(4, ": ").collect();
            if parts.len() != 4 || parts[0] != "error" || parts[1].is_empty() || parts[2].is_empty()
            {
                return Err(format!("not `error: FILE: FIELD: what`: {}", lines[0]));
            }
            if lines[0].chars().count() > 1000 {
                return Err(format!("line of {} chars", lines[0].chars().count()));
            }
            if let Some(out) = &case.out {
                let names: Vec<_> = std::fs::read_dir(out)
                    .map_err(|e| e.to_string())?
                    .map(|e| e.unwrap().file_name())
                    .collect();
                let sentinel = std::fs::read(out.join("sentinel.txt")).unwrap_or_default();
                if names.len() != 1 || sentinel != b"keep\n" {
                    return Err(format!("refused run touched {}: {names:?}", out.display()));
                }
            }
        }
        other => {
            return Err(format!("exit {other:?}; stderr: {stderr}"));
        }
    }
    if stderr.contains("panicked") {
        return Err(format!("panic: {stderr}"));
    }
    Ok(took)
}

#[test]
fn fuzz_the_input_contract() {
    let seed: u64 = std::env::var("MUFE_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(9);
    let n_cases: usize = std::env::var("MUFE_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(600);
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz_scenes");
    if work.exists() {
        std::fs::remove_dir_all(&work).unwrap();
    }
    std::fs::create_dir_all(&work).unwrap();
    let bases = base_scenes();
    let texts: Vec<String> = bases
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut cases = Vec::with_capacity(n_cases);
    for id in 0..n_cases {
        let b = rng.below(bases.len());
        let out = work.join(format!("out{id}"));
        if rng.below(12) == 0 {
            let args =
                bad_command_line(&mut rng, bases[b].to_str().unwrap(), out.to_str().unwrap());
            cases.push(Case {
                id,
                class: "bad command line",
                args,
                out: None,
            });
            continue;
        }
        let (class, bytes) = mutate(&mut rng, &texts[b]);
        let scene = work.join(format!("case{id}.toml"));
        std::fs::write(&scene, bytes).unwrap();
        let scene = scene.display().to_string();
        // One case in eight is a run into an existing directory with a sentinel file.
        if rng.below(8) == 0 {
            std::fs::create_dir_all(&out).unwrap();
            std::fs::write(out.join("sentinel.txt"), b"keep\n").unwrap();
            let args = [
                "run",
                &scene,
                "--out",
                out.to_str().unwrap(),
                "--max-steps",
                "3",
                "--threads",
                "1",
                "--quiet",
            ]
            .map(String::from)
            .to_vec();
            cases.push(Case {
                id,
                class,
                args,
                out: Some(out),
            });
        } else {
            cases.push(Case {
                id,
                class,
                args: vec!["check".into(), scene],
                out: None,
            });
        }
    }

    let t0 = Instant::now();
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let counts = Mutex::new(std::collections::BTreeMap::<&str, usize>::new());
    let slowest = Mutex::new(Duration::ZERO);
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = cases.get(i) else { break };
                *counts.lock().unwrap().entry(case.class).or_default() += 1;
                match check_case(case) {
                    Ok(took) => {
                        let mut m = slowest.lock().unwrap();
                        *m = (*m).max(took);
                    }
                    Err(e) => failures.lock().unwrap().push(format!(
                        "case {} ({}), mufe {}: {e}",
                        case.id,
                        case.class,
                        case.args
                            .iter()
                            .map(|a| if a.len() > 100 {
                                format!("{}…", &a[..100])
                            } else {
                                a.clone()
                            })
                            .collect::<Vec<_>>()
                            .join(" ")
                    )),
                }
            });
        }
    });
    let wall = t0.elapsed();
    eprintln!(
        "fuzz: {} cases (seed {seed}) in {:.1} s, slowest {:.2} s; classes {:?}",
        cases.len(),
        wall.as_secs_f64(),
        slowest.lock().unwrap().as_secs_f64(),
        counts.lock().unwrap()
    );
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(cases.len() >= 500 || n_cases < 500);
}

/// Accepted scenes shrunk under an element budget run 3 steps with finite energies.
#[test]
fn accepted_scenes_run_three_finite_steps() {
    let work = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz_runs");
    if work.exists() {
        std::fs::remove_dir_all(&work).unwrap();
    }
    let cases: [(&str, &[&str]); 4] = [
        ("tests/fixtures/valid_small.toml", &[]),
        (
            "jobs/examples/free_vibration.toml",
            &["grains[0].shape.sphere.seeding=4e-4"],
        ),
        ("jobs/tests/wall_friction.toml", &[]),
        (
            "jobs/tests/contact_head_on.toml",
            &[
                "grains[0].shape.sphere.seeding=4e-4",
                "grains[1].shape.sphere.seeding=4e-4",
                "grains[0].shape.sphere.refine[0].seeding=2e-4",
                "grains[1].shape.sphere.refine[0].seeding=2e-4",
            ],
        ),
    ];
    for (i, (scene, sets)) in cases.iter().enumerate() {
        let out = work.join(format!("run{i}"));
        let mut args: Vec<String> = [
            "run",
            &root().join(scene).display().to_string(),
            "--out",
            out.to_str().unwrap(),
            "--max-steps",
            "3",
            "--threads",
            "1",
            "--quiet",
        ]
        .map(String::from)
        .to_vec();
        for s in *sets {
            args.push("--set".into());
            args.push(s.to_string());
        }
        let (code, _, err, _) = run_case(&args).unwrap();
        assert_eq!(code, Some(0), "{scene}: {err}");
        let file = hdf5::File::open(out.join("results.h5")).unwrap();
        for name in [
            "energy_balance",
            "kinetic_energy",
            "strain_energy",
            "external_work",
        ] {
            let v = file
                .dataset(&format!("history/{name}"))
                .unwrap()
                .read_raw::<f64>()
                .unwrap();
            assert!(!v.is_empty(), "{scene}: empty {name}");
            assert!(v.iter().all(|x| x.is_finite()), "{scene}: {name} = {v:?}");
        }
    }
}
