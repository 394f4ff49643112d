//! `cargo test --workspace` builds a package's binary only for that
//! package's own integration tests. The tests here and `exo run` spawn
//! every service binary, so every package with a service binary keeps an
//! integration test of its own: without one, a fresh clone's test run
//! fails with "exo-… is not built" (it happened to exo-tunnel in CI).

use exo_tests::workspace_root;

#[test]
fn every_service_binary_is_built_by_the_test_command() {
    let root = workspace_root();
    let mut missing = Vec::new();
    let mut dirs: Vec<_> = std::fs::read_dir(root.join("services"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    dirs.push(root.join("tools/exo"));
    for dir in dirs {
        if !dir.join("src/main.rs").exists() {
            continue;
        }
        let has_test = std::fs::read_dir(dir.join("tests"))
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .any(|e| e.path().extension().is_some_and(|x| x == "rs"))
            })
            .unwrap_or(false);
        if !has_test {
            missing.push(dir.display().to_string());
        }
    }
    assert!(
        missing.is_empty(),
        "binary packages without an integration test of their own (their binary is not built by `cargo test --workspace`): {missing:?}"
    );
}

/// The layers the folders show (ARCHITECTURE.md, "Layers"): `shared/`
/// below `services/` below `tools/` below `tests/`. Every workspace crate
/// imports (normal, build and dev dependencies alike) only crates of its
/// own layer or below (a test may use the test support of `tests/`), and a
/// service imports no other service: each process builds, runs and
/// restarts on its own. Read from the manifests, as `cargo metadata` would
/// give them.
#[test]
fn no_crate_imports_from_a_layer_above_and_no_service_imports_another() {
    let root = workspace_root();
    let manifest = |dir: &std::path::Path| -> toml::Table {
        let file = dir.join("Cargo.toml");
        let text =
            std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        text.parse()
            .unwrap_or_else(|e| panic!("{}: {e}", file.display()))
    };
    let members: Vec<String> = manifest(&root)["workspace"]["members"]
        .as_array()
        .expect("workspace.members")
        .iter()
        .map(|m| m.as_str().expect("a path").to_string())
        .collect();
    let layer = |path: &str| match path.split('/').next() {
        Some("shared") => 0,
        Some("services") => 1,
        Some("tools") => 2,
        Some("tests") => 3,
        other => panic!("{path}: {other:?} is no layer"),
    };
    // Crate name → (layer, folder).
    let mut crates = std::collections::BTreeMap::new();
    for m in &members {
        let t = manifest(&root.join(m));
        let name = t["package"]["name"]
            .as_str()
            .expect("package.name")
            .to_string();
        crates.insert(name, (layer(m), m.clone()));
    }
    let mut wrong = Vec::new();
    for m in &members {
        let t = manifest(&root.join(m));
        let me = t["package"]["name"].as_str().expect("package.name");
        for kind in ["dependencies", "dev-dependencies", "build-dependencies"] {
            let Some(deps) = t.get(kind).and_then(|d| d.as_table()) else {
                continue;
            };
            for dep in deps.keys() {
                let Some(&(theirs, ref folder)) = crates.get(dep) else {
                    continue;
                };
                let mine = layer(m);
                // Tests anywhere may use the test support (`tests/`'s
                // library: child processes, scratch directories).
                let test_support = kind == "dev-dependencies" && theirs == 3;
                if theirs > mine && !test_support {
                    wrong.push(format!(
                        "{me} ({m}) imports {dep} ({folder}) from a layer above ({kind})"
                    ));
                } else if mine == 1 && theirs == 1 && dep != me {
                    wrong.push(format!(
                        "{me} ({m}) imports the service {dep} ({folder}) ({kind})"
                    ));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// `test = false` (issue 31 item 2: no test binary for a target without
/// tests; each costs a link and 20–45 MB) must never hide a test: every
/// library so marked holds no `#[test]` or `#[cfg(test)]` anywhere under
/// its `src/`, and every binary so marked is one file (no `mod`) without
/// them. A test added there later fails this one instead of never running.
#[test]
fn no_target_left_out_of_cargo_test_holds_a_test() {
    let root = workspace_root();
    let manifest: toml::Table = std::fs::read_to_string(root.join("Cargo.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let has_test = |text: &str| text.contains("#[test]") || text.contains("#[cfg(test)]");
    fn rs_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                rs_files(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut hidden = Vec::new();
    let mut left_out = 0;
    for m in manifest["workspace"]["members"].as_array().unwrap() {
        let dir = root.join(m.as_str().unwrap());
        let t: toml::Table = std::fs::read_to_string(dir.join("Cargo.toml"))
            .unwrap()
            .parse()
            .unwrap();
        let off =
            |target: &toml::Value| target.get("test").and_then(toml::Value::as_bool) == Some(false);
        if t.get("lib").is_some_and(off) {
            left_out += 1;
            let mut files = Vec::new();
            rs_files(&dir.join("src"), &mut files);
            for f in files {
                if has_test(&std::fs::read_to_string(&f).unwrap()) {
                    hidden.push(f.display().to_string());
                }
            }
        }
        for bin in t
            .get("bin")
            .and_then(toml::Value::as_array)
            .into_iter()
            .flatten()
        {
            if off(bin) {
                left_out += 1;
                let f = dir.join(
                    bin["path"]
                        .as_str()
                        .expect("a [[bin]] with test = false names its path"),
                );
                let text = std::fs::read_to_string(&f).unwrap();
                if has_test(&text) || text.lines().any(|l| l.trim_start().starts_with("mod ")) {
                    hidden.push(f.display().to_string());
                }
            }
        }
    }
    assert!(
        left_out > 0,
        "no target has test = false: this test checks nothing"
    );
    assert!(
        hidden.is_empty(),
        "targets with test = false that hold tests (cargo test would never run them): {hidden:?}"
    );
}
