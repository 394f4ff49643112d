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
