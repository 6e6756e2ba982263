//! Split renders end to end: `lucent render --part K/N --partial` for every
//! share, then `lucent merge`, must write PNG and EXR files byte-identical
//! to one `lucent render`, for N = 1, 2, 3 and 7 and both integrators; bad
//! parts are refused by name with exit code 1; a turntable's frame ranges
//! make the same files as the whole orbit.

mod common;

use common::{run_err, run_ok, s, scratch};
use std::path::{Path, PathBuf};

/// The Cornell box, small: a quick render in a debug build.
const SCENE: &str = "res/scenes/cornell-mitsuba.toml";

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Renders the `n` shares of a render with `quality` into `dir` and returns
/// their paths.
fn parts(dir: &Path, quality: &str, n: u32) -> Vec<PathBuf> {
    (1..=n)
        .map(|k| {
            let p = dir.join(format!("n{n}.{k}.lpart"));
            run_ok(&format!("render {SCENE} --part {k}/{n} {quality} --partial"), &[s(&p)]);
            p
        })
        .collect()
}

#[test]
fn merged_shares_are_byte_identical_to_one_render_for_both_integrators() {
    for (name, quality) in [
        ("path", "--size 20x16 --spp 7 --integrator path --max-depth 6"),
        ("whitted", "--size 20x16 --spp 7 --integrator whitted --shading phong"),
    ] {
        let dir = scratch("split", name);
        let (png, exr) = (dir.join("one.png"), dir.join("one.exr"));
        run_ok(
            &format!("render {SCENE} --exposure 1.5 {quality}"),
            &["-o", s(&png), "--exr", s(&exr)],
        );
        for n in [1, 2, 3, 7] {
            let parts = parts(&dir, quality, n);
            let (m_png, m_exr) = (dir.join(format!("m{n}.png")), dir.join(format!("m{n}.exr")));
            let mut args = vec!["-o", s(&m_png), "--exr", s(&m_exr), "--exposure", "1.5"];
            // In reverse order: the order of the parts does not matter.
            args.extend(parts.iter().rev().map(|p| s(p)));
            let summary = run_ok("merge", &args);
            assert!(summary.contains(&format!("merged {n} parts")), "{summary}");
            assert!(read(&m_png) == read(&png), "{name}: PNG of {n} merged parts differs");
            assert!(read(&m_exr) == read(&exr), "{name}: EXR of {n} merged parts differs");
        }
    }
}

#[test]
fn bad_parts_are_refused_by_name_and_a_rerun_replaces_a_share() {
    let dir = scratch("split", "bad");
    let q = "--size 12x8 --spp 3 --integrator path";
    let p = parts(&dir, q, 3);
    let out = dir.join("x.png");
    let merge = |run: fn(&str, &[&str]) -> String, parts: &[&Path]| {
        let mut args = vec!["-o", s(&out)];
        args.extend(parts.iter().map(|p| s(p)));
        run("merge", &args)
    };
    let err = |parts: &[&Path]| merge(run_err, parts);
    assert!(err(&[&p[0], &p[2]]).contains("missing share 2/3 of 3"));
    let dup = err(&[&p[0], &p[1], &p[1], &p[2]]);
    assert!(dup.contains("n3.2.lpart: share 2/3 again"), "{dup}");
    // A share rendered with other settings names the setting.
    run_ok(
        &format!("render {SCENE} --part 2/3 {q} --seed 5 --partial"),
        &[s(&p[1])],
    );
    let e = err(&[&p[0], &p[1], &p[2]]);
    assert!(
        e.contains("n3.2.lpart: does not belong with") && e.contains("'seed: 5' here, 'seed: 0' there"),
        "{e}"
    );
    // Re-running the share replaces the file.
    run_ok(&format!("render {SCENE} --part 2/3 {q} --partial"), &[s(&p[1])]);
    merge(run_ok, &[&p[0], &p[1], &p[2]]);
    assert!(
        !std::fs::read_dir(&dir)
            .unwrap()
            .any(|e| e.unwrap().file_name().to_string_lossy().contains(".tmp."))
    );
    // Truncated and corrupted files.
    let bytes = read(&p[2]);
    let cut = dir.join("cut.lpart");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    assert!(err(&[&p[0], &p[1], &cut]).contains("cut.lpart: truncated"));
    let mut flipped = bytes.clone();
    flipped[bytes.len() - 100] ^= 1;
    let bad = dir.join("bad.lpart");
    std::fs::write(&bad, &flipped).unwrap();
    assert!(err(&[&p[0], &p[1], &bad]).contains("bad.lpart: corrupted"));
    let png = dir.join("not.lpart");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n").unwrap();
    assert!(err(&[&png]).contains("not a Lucent partial file"));
    // Another scene.
    let other = dir.join("other.lpart");
    run_ok(
        &format!("render res/scenes/seed.toml --part 3/3 {q} --partial"),
        &[s(&other)],
    );
    assert!(err(&[&p[0], &p[1], &other]).contains("other.lpart: does not belong with"));
    // More shares than samples is refused before rendering.
    let e = run_err(
        &format!("render {SCENE} --part 1/4 --spp 3 --partial"),
        &[s(&dir.join("y.lpart"))],
    );
    assert!(e.contains("at most 3 shares"), "{e}");
    assert!(!dir.join("y.lpart").exists());
}

#[test]
fn turntable_frame_ranges_make_the_frames_of_the_whole_orbit() {
    let dir = scratch("split", "turntable");
    let turntable = format!("render {SCENE} --size 16x12 --spp 1 --turntable 4");
    let all = dir.join("all");
    let pattern = format!("{}/f###.png", s(&all));
    std::fs::create_dir_all(&all).unwrap();
    let summary = run_ok(&turntable, &["-o", &pattern]);
    assert_eq!(summary.lines().count(), 4, "{summary}");
    let part = dir.join("part");
    std::fs::create_dir_all(&part).unwrap();
    let pattern = format!("{}/f###.png", s(&part));
    for range in ["0..1", "1..4"] {
        run_ok(&turntable, &["--frames", range, "-o", &pattern]);
    }
    for f in 0..4 {
        let name = format!("f{f:03}.png");
        assert!(read(&all.join(&name)) == read(&part.join(&name)), "{name}");
    }
    assert!(
        read(&all.join("f000.png")) != read(&all.join("f002.png")),
        "the camera turns"
    );
    // Frame 0 is the plain render.
    let plain = dir.join("plain.png");
    run_ok(&format!("render {SCENE} --size 16x12 --spp 1 -o"), &[s(&plain)]);
    assert!(read(&plain) == read(&all.join("f000.png")));
    let e = run_err(&turntable, &["--frames", "2..5", "-o", &pattern]);
    assert!(e.contains("frames 0 to 3"), "{e}");
    let e = run_err(&turntable, &["-o", s(&plain)]);
    assert!(e.contains("needs '#'"), "{e}");
}
