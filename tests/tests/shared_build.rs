//! The README's commands share one release build: the wheel (`pip install ./python`), the CLI
//! (`cargo run --release -p tessera`) and the tests (`cargo test --workspace --release`). Cargo
//! reuses a compiled crate only when its features are the same, and a test build adds the
//! features its dev-dependencies turn on; `workspace-hack/Cargo.toml` turns them on everywhere.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

/// Every package a build compiles, with the feature lists it compiles it with: one list, or two
/// when build scripts or proc-macros need it compiled for the host with other features.
fn features(selection: &[&str], edges: &str) -> BTreeMap<String, BTreeSet<String>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let out = Command::new(env!("CARGO"))
        .args(["tree", "--frozen", "--prefix", "none", "--format", "{p}|{f}", "--edges", edges])
        .args(["--target", "x86_64-unknown-linux-gnu"])
        .args(selection)
        .current_dir(root)
        .output()
        .expect("cargo runs");
    assert!(out.status.success(), "cargo tree {selection:?}: {}", String::from_utf8_lossy(&out.stderr));
    let mut packages = BTreeMap::<String, BTreeSet<String>>::new();
    for line in String::from_utf8(out.stdout).expect("cargo tree prints UTF-8").lines() {
        let line = line.trim_end_matches(" (*)");
        if let Some((package, features)) = line.split_once('|') {
            let package = package.trim_end_matches(" (proc-macro)").trim();
            packages.entry(package.to_string()).or_default().insert(features.to_string());
        }
    }
    packages
}

#[test]
fn the_release_builds_share_one_feature_set() {
    let tests = features(&["--workspace"], "normal,build,dev");
    for selection in [["-p", "tessera-python"], ["-p", "tessera"]] {
        let build = features(&selection, "normal,build");
        let differ: Vec<String> = build
            .iter()
            .filter(|(package, sets)| tests.get(*package).is_some_and(|t| t != *sets))
            .map(|(package, sets)| format!("{package}: {sets:?} alone, {:?} in the tests", tests[package]))
            .collect();
        assert!(
            differ.is_empty(),
            "{selection:?} compiles these crates with other features than the test build (add them to workspace-hack):\n{}",
            differ.join("\n")
        );
        assert!(build.len() > 200, "cargo tree listed only {} packages for {selection:?}", build.len());
    }
}
