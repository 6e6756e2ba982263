//! End-to-end tests of the `lucent` binary: exit codes, one-line errors
//! that name file, line and column, PNG output, and the viewer (in a real
//! window when a display is available, e.g. under Xvfb in CI).

mod common;

use common::{lucent, lucent_with, run_err, run_fail, run_ok, s, scratch, stderr};

/// Runs `lucent render` on a scene text and returns the error output, which
/// must be one `error:` line with a non-zero exit code and no panic.
fn render_error(name: &str, scene_text: &str) -> String {
    let dir = scratch("cli", name);
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, scene_text).unwrap();
    let err = run_fail(1, "render", &[s(&scene), "-o", s(&dir.join("x.png"))]);
    let lines: Vec<&str> = err.lines().filter(|l| !l.starts_with("warning:")).collect();
    assert_eq!(lines.len(), 1, "one error line expected: {err}");
    assert!(!dir.join("x.png").exists(), "no output on error");
    lines[0].replace(&dir.display().to_string(), "DIR")
}

#[test]
fn path_traces_the_cornell_box_to_exr_and_an_exposed_png() {
    let dir = scratch("cli", "cornell");
    let (exr, png, bright) = (dir.join("c.exr"), dir.join("c.png"), dir.join("bright.png"));
    let run = |extra: &[&str]| run_ok("render res/scenes/cornell-mitsuba.toml --size 24x24 --spp 2", extra);
    let summary = run(&["--exr", s(&exr), "-o", s(&png)]);
    assert!(summary.contains("path max_depth 16"), "{summary}");
    let (w, h, rgb) = lucent_assets::decode_exr(&std::fs::read(&exr).unwrap(), &exr).unwrap();
    assert_eq!((w, h, rgb.len()), (24, 24, 24 * 24 * 3));
    assert!(rgb.iter().all(|v| v.is_finite() && *v >= 0.0));
    // The light (radiance 15) is in the picture, unclamped in the EXR.
    assert!(rgb.iter().any(|v| *v > 10.0), "no light in the EXR");
    // The same render two stops brighter: no PNG value darker.
    run(&["--exposure", "2", "-o", s(&bright)]);
    let a = lucent_assets::texture_from_bytes(&std::fs::read(&png).unwrap(), &png).unwrap();
    let b = lucent_assets::texture_from_bytes(&std::fs::read(&bright).unwrap(), &bright).unwrap();
    let (mut brighter, mut darker) = (0, 0);
    for y in 0..24 {
        for x in 0..24 {
            let (pa, pb) = (a.texel(x, y), b.texel(x, y));
            darker += usize::from(pb.cmplt(pa).any());
            brighter += usize::from(pb.cmpgt(pa).any());
        }
    }
    assert_eq!(darker, 0);
    assert!(brighter > 24 * 24 / 2, "{brighter}");
    // --exr alone is enough; a wrong extension is an error.
    run(&["--exr", s(&exr), "--integrator", "whitted"]);
    let err = run_err("render res/scenes/cornell-mitsuba.toml --exr x.png", &[]);
    assert!(err.contains("must end in .exr"), "{err}");
}

#[test]
fn renders_the_seed_scene_to_png() {
    let dir = scratch("cli", "seed");
    let png = dir.join("seed.png");
    let summary = run_ok(
        "render res/scenes/seed.toml --size 96x54 --spp 1 --threads 2 -o",
        &[s(&png)],
    );
    assert!(
        summary.contains("96x54, 1 spp") && summary.contains("Mrays/s"),
        "{summary}"
    );
    let tex = lucent_assets::texture_from_bytes(&std::fs::read(&png).unwrap(), &png).unwrap();
    assert_eq!((tex.width(), tex.height()), (96, 54));
}

#[test]
fn bad_toml_is_located() {
    let err = render_error("bad_toml", "[camera]\nradius = 2.0\ntheta_deg = [\n");
    assert!(err.starts_with("error: DIR/scene.toml:3:14: "), "{err}");
}

#[test]
fn unknown_material_is_located() {
    let text = "[materials.red]\nkd = 1\n\n[[objects]]\nshape = \"cube\"\nmaterial = \"blue\"\n";
    let err = render_error("unknown_material", text);
    assert_eq!(
        err,
        "error: DIR/scene.toml:6:12: unknown material 'blue' (defined: red)"
    );
}

#[test]
fn missing_mesh_file_is_located() {
    let err = render_error("missing_mesh", "[[objects]]\nmesh = \"nowhere/bunny.ply\"\n");
    assert!(
        err.starts_with("error: DIR/scene.toml:2:8: cannot load mesh 'nowhere/bunny.ply': DIR/nowhere/bunny.ply: "),
        "{err}"
    );
}

#[test]
fn missing_scene_file_and_bad_output_are_errors() {
    let err = run_err("render no/such/scene.toml -o /tmp/x.png", &[]);
    assert!(err.starts_with("error: no/such/scene.toml: "), "{err}");
    let err = run_err("render res/scenes/seed.toml -o x.jpg", &[]);
    assert!(err.contains("only PNG output"), "{err}");
    // Malformed flags are usage errors (exit code 2), caught by clap.
    let err = run_fail(2, "render res/scenes/seed.toml -o x.png --size 0x10", &[]);
    assert!(err.contains("not a size from 1 to 16384"), "{err}");
}

#[test]
fn viewer_without_a_display_points_to_headless_rendering() {
    let out = lucent()
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = stderr(&out);
    assert!(err.contains("no display") && err.contains("lucent render"), "{err}");
    assert!(!err.contains("panicked"));
}

#[test]
fn help_lists_the_viewer_controls() {
    // The viewer is the default command, so plain --help lists its keys too.
    let help = run_ok("--help", &[]);
    assert!(help.contains("Controls:") && help.contains("left mouse drag"), "{help}");
    let help = run_ok("view --help", &[]);
    for key in [
        "arrow keys",
        "mouse drag",
        "wheel",
        "F1-F4 or 1-4",
        "switch integrator",
        "screenshot",
        "Esc",
        "--stats",
        "--max-spp",
        "--preset",
    ] {
        assert!(help.contains(key), "{help}");
    }
}

#[test]
fn viewer_opens_renders_and_saves_a_screenshot() {
    if std::env::var_os("DISPLAY").is_none() {
        eprintln!("skipped: no DISPLAY (CI runs this under Xvfb)");
        return;
    }
    let dir = scratch("cli", "viewer");
    let shot = dir.join("shot.png");
    run_ok("view --frames 4 --size 160x90 --screenshot", &[s(&shot)]);
    let tex = lucent_assets::texture_from_bytes(&std::fs::read(&shot).unwrap(), &shot).unwrap();
    assert_eq!((tex.width(), tex.height()), (160, 90));
    // The seed scene fills much of the frame with lit objects and floor.
    let bright = (0..90i64)
        .flat_map(|y| (0..160i64).map(move |x| (x, y)))
        .filter(|&(x, y)| tex.texel(x, y).max_element() > 0.1)
        .count();
    assert!(bright > 160 * 90 / 4, "only {bright} lit pixels");
}

#[test]
fn bench_render_measures_the_specialised_and_the_all_features_renderer() {
    let bench = "bench render res/scenes/seed.toml --size 24x16 --spp 1 --reps 1";
    let json = |extra: &str| {
        let stdout = run_ok(&format!("{bench} {extra}"), &[]);
        serde_json::from_str::<serde_json::Value>(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"))
    };
    let lean = json("--without sphere");
    assert_eq!(lean["all_features"], false);
    assert_eq!(
        lean["features"],
        serde_json::json!(["reflective", "textured", "directional_lights", "smooth_normals"])
    );
    let all = json("--without sphere --all-features");
    assert_eq!(all["all_features"], true);
    assert_eq!(all["features"].as_array().map(Vec::len), Some(9));
    // The same image means the same rays.
    assert_eq!(lean["rays"], all["rays"]);
    assert!(lean["triangles"].as_u64() < json("")["triangles"].as_u64());
    let err = run_fail(1, &format!("{bench} --without teapot"), &[]);
    assert!(err.contains("no object named 'teapot'"), "{err}");
}

#[test]
fn an_unwritable_output_fails_before_rendering() {
    let dir = scratch("cli", "unwritable");
    for flag in ["-o", "--exr"] {
        let ext = if flag == "-o" { "png" } else { "exr" };
        let target = dir.join(format!("no/such/dir/x.{ext}"));
        let out = lucent().arg("render").arg(flag).arg(&target).output().unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.starts_with(&format!("error: {}: cannot write the output here", target.display())),
            "{err}"
        );
        assert!(out.stdout.is_empty(), "nothing rendered");
    }
    // A writable path is left as it was found: no empty file behind.
    run_fail(2, "render --size 0x1 -o", &[s(&dir.join("x.png"))]);
    assert!(!dir.join("x.png").exists());
}

#[test]
fn render_takes_the_built_in_scene_and_quiet_and_verbose_flags() {
    let dir = scratch("cli", "builtin");
    let png = dir.join("seed.png");
    let summary = run_ok("render --size 32x18 --spp 1 -o", &[s(&png)]);
    assert!(summary.contains("32x18, 1 spp"), "{summary}");
    assert!(png.exists());
    let verbose = lucent_with("render --size 32x18 --spp 1 -v -o", &[s(&png)])
        .output()
        .unwrap();
    let err = stderr(&verbose);
    assert!(err.contains("note: built-in seed scene: loaded in"), "{err}");
    // A mesh whose MTL file is missing loads with a warning (magenta).
    let obj = "mtllib nowhere.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, "[[objects]]\nmesh = \"m.obj\"\n").unwrap();
    let with_scene = |flags: &str| {
        let cmd = format!("render --size 8x8 {flags} -o");
        lucent_with(&cmd, &[s(&png), s(&scene)]).output().unwrap()
    };
    let out = with_scene("");
    assert!(
        out.status.success() && stderr(&out).starts_with("warning: "),
        "{}",
        stderr(&out)
    );
    let out = with_scene("-q");
    assert!(out.status.success() && stderr(&out).is_empty(), "{}", stderr(&out));
}
