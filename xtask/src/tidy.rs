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
//! - no `unwrap()`, `expect(`, `panic!`, `todo!`, `unimplemented!` or
//!   `unreachable!` in the crates' code outside tests and doc comments,
//!   unless the comment line above says `// ok: <why it cannot fail>`
//!   (data must never reach a panic);
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
    check_panics(root, &files, &mut problems);
    if problems.is_empty() { Ok(()) } else { Err(problems) }
}

/// What can panic, as it is written.
const PANICS: &[&str] = &[
    ".unwrap()",
    ".expect(",
    "panic!(",
    "todo!(",
    "unimplemented!(",
    "unreachable!(",
];

/// Flags each panic site in `crates/*/src` outside test modules (inline
/// `#[cfg(test)]` blocks and the files `#[cfg(test)] mod x;` names) and
/// doc comments that no `// ok:` comment line above explains.
fn check_panics(root: &Path, files: &[PathBuf], problems: &mut Vec<String>) {
    let src: Vec<&PathBuf> = files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rs") && p.components().any(|c| c.as_os_str() == "src"))
        .filter(|p| p.strip_prefix(root).is_ok_and(|r| r.starts_with("crates")))
        .collect();
    let mut test_files = Vec::new();
    for path in &src {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let lines: Vec<&str> = text.lines().map(str::trim).collect();
        for (i, l) in lines.iter().enumerate() {
            let next = lines[i + 1..].iter().find(|l| !l.starts_with("#["));
            let Some(name) = next.and_then(|n| n.strip_prefix("mod ")?.strip_suffix(';')) else {
                continue;
            };
            if *l == "#[cfg(test)]" {
                let dir = path.parent().unwrap_or(root);
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                test_files.push(dir.join(format!("{name}.rs")));
                test_files.push(dir.join(&stem).join(format!("{name}.rs")));
            }
        }
    }
    for path in src.into_iter().filter(|p| !test_files.contains(p)) {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let rel = path.strip_prefix(root).unwrap_or(path).display();
        let (mut depth, mut test_at, mut pending, mut explained) = (0i32, None, false, false);
        for (i, line) in text.lines().enumerate() {
            let l = line.trim();
            let code = if l.starts_with("//") {
                ""
            } else {
                l.split("//").next().unwrap_or("")
            };
            if l == "#[cfg(test)]" {
                pending = true;
            } else if pending && test_at.is_none() && code.contains('{') {
                (test_at, pending) = (Some(depth), false);
            } else if pending && code.ends_with(';') {
                pending = false;
            }
            if test_at.is_none() && PANICS.iter().any(|p| code.contains(p)) && !explained && !l.contains("// ok:") {
                problems.push(format!(
                    "{rel}:{}: can panic; handle the case, or say why it cannot fail in a `// ok:` comment above",
                    i + 1
                ));
            }
            if l.starts_with("//") {
                explained |= l.starts_with("// ok:");
            } else {
                explained = false;
            }
            depth += code.matches('{').count() as i32 - code.matches('}').count() as i32;
            if test_at.is_some_and(|d| depth <= d) {
                test_at = None;
            }
        }
    }
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
    fn panic_rule_flags_library_code_only() {
        let root = std::env::temp_dir().join(format!("lucent-tidy-{}", std::process::id()));
        let src = root.join("crates/k/src");
        let _ = std::fs::create_dir_all(&src);
        let lib = "//! k\nfn a() { x.unwrap(); }\n// ok: checked above\nfn b() { x.unwrap(); }\n\
                   fn c() { x.unwrap(); } // ok: same line\n#[cfg(test)]\nmod tests {\n    fn t() { x.unwrap(); }\n}\n\
                   /// x.unwrap() in a doc\nfn d() { panic!(\"{e}\") }\n#[cfg(test)]\nmod unit;\nmod m;\n";
        let files = [src.join("lib.rs"), src.join("unit.rs"), src.join("m.rs")];
        for (f, text) in files.iter().zip([
            lib,
            "//! t\nfn u() { x.unwrap(); }\n",
            "//! m\nfn v() { x.expect(\"\"); }\n",
        ]) {
            std::fs::write(f, text).unwrap();
        }
        let mut problems = Vec::new();
        check_panics(&root, &files, &mut problems);
        let _ = std::fs::remove_dir_all(&root);
        let lines: Vec<&str> = problems.iter().map(|p| p.split(": can").next().unwrap_or("")).collect();
        assert_eq!(
            lines,
            ["crates/k/src/lib.rs:2", "crates/k/src/lib.rs:11", "crates/k/src/m.rs:2"]
        );
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
