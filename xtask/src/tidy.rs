//! Repository rules, checked by `cargo xtask tidy` and by the test below
//! (so `cargo test` enforces them):
//! - every Rust file starts with a `//!` comment saying what it is for;
//! - dependency ownership: hecs only in lucent-scene, minifb only in the
//!   app, tobj/gltf/draco-core/mikktspace/image only in lucent-assets (image also in
//!   the test package), rayon only in lucent-render and lucent-accel, nv-flip and
//!   plotters (measuring and plotting tools, C++ in nv-flip's case) only
//!   in xtask, exr only in lucent-assets, libloading (which loads Intel
//!   Open Image Denoise at run time) only in lucent-denoise;
//! - no `#[should_panic]` or `#[ignore]` tests (assert on `Err` instead);
//! - no trailing whitespace in our sources and docs (asset data under
//!   `res/meshes` is kept byte-for-byte as shipped and is exempt).

use std::path::{Path, PathBuf};

/// Which crates (directory names) may list each external dependency.
const OWNERS: &[(&str, &[&str])] = &[
    ("hecs", &["lucent-scene"]),
    ("minifb", &["lucent"]),
    ("tobj", &["lucent-assets"]),
    ("gltf", &["lucent-assets"]),
    ("draco-core", &["lucent-assets"]),
    ("mikktspace", &["lucent-assets"]),
    ("image", &["lucent-assets", "tests"]),
    ("rayon", &["lucent-render", "lucent-accel"]),
    ("nv-flip", &["xtask"]),
    ("plotters", &["xtask"]),
    ("exr", &["lucent-assets"]),
    ("libloading", &["lucent-denoise"]),
];

/// Checks every rule; returns the problems found, one line each.
pub fn check(root: &Path) -> Result<(), Vec<String>> {
    let mut problems = Vec::new();
    let mut files = Vec::new();
    for dir in ["crates", "tests", "xtask", "docs", "fuzz"] {
        walk(&root.join(dir), &mut files);
    }
    for f in ["README.md", "ARCHITECTURE.md", "Cargo.toml"] {
        files.push(root.join(f));
    }
    for path in &files {
        let Ok(text) = std::fs::read_to_string(path) else {
            continue;
        };
        let rel = path.strip_prefix(root).unwrap_or(path).display().to_string();
        let is_rs = rel.ends_with(".rs");
        if is_rs && !text.starts_with("//!") {
            problems.push(format!(
                "{rel}: must start with a `//!` comment saying what the file does"
            ));
        }
        if is_rs && rel != "xtask/src/tidy.rs" {
            for bad in ["#[should_panic", "#[ignore"] {
                if text.contains(bad) {
                    problems.push(format!(
                        "{rel}: uses {bad}]; assert on Err or skip with a message instead"
                    ));
                }
            }
        }
        if let Some((i, _)) = text
            .lines()
            .enumerate()
            .find(|(_, l)| l.ends_with(' ') || l.ends_with('\t'))
        {
            problems.push(format!("{rel}:{}: trailing whitespace", i + 1));
        }
        if rel.ends_with("Cargo.toml") && rel != "Cargo.toml" {
            check_owners(&rel, &text, &mut problems);
        }
    }
    if problems.is_empty() { Ok(()) } else { Err(problems) }
}

fn check_owners(rel: &str, manifest: &str, problems: &mut Vec<String>) {
    let crate_dir = Path::new(rel)
        .parent()
        .and_then(Path::file_name)
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    for (dep, owners) in OWNERS {
        let listed = manifest.lines().any(|l| {
            let l = l.trim_start();
            l.starts_with(&format!("{dep} ")) || l.starts_with(&format!("{dep}=")) || l.starts_with(&format!("{dep}."))
        });
        if listed && !owners.contains(&crate_dir.as_str()) {
            problems.push(format!(
                "{rel}: lists `{dep}`, which only {} may depend on",
                owners.join(" and ")
            ));
        }
    }
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if p.is_dir() {
            // Fuzzing's generated inputs and outputs are not sources.
            let generated = ["target", "snapshots", "corpus", "artifacts", "logs", "coverage"];
            if !generated.contains(&name.as_str()) {
                walk(&p, out);
            }
        } else if [".rs", ".toml", ".md"].iter().any(|ext| name.ends_with(ext)) {
            out.push(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repository_is_tidy() {
        if let Err(problems) = check(&crate::root()) {
            panic!("tidy found problems:\n{}", problems.join("\n"));
        }
    }

    #[test]
    fn ownership_rule_catches_a_stray_dependency() {
        let mut problems = Vec::new();
        check_owners(
            "crates/lucent-render/Cargo.toml",
            "[dependencies]\nhecs.workspace = true\n",
            &mut problems,
        );
        assert_eq!(problems.len(), 1, "{problems:?}");
        let mut problems = Vec::new();
        check_owners(
            "crates/lucent-scene/Cargo.toml",
            "[dependencies]\nhecs.workspace = true\n",
            &mut problems,
        );
        assert!(problems.is_empty());
    }
}
