//! End-to-end tests of `--preset` on the `lucent` binary: the preset's
//! size and settings reach the render, explicit flags win, and an unknown
//! name is a usage error that lists the presets.

mod common;

use common::{run_fail, run_ok, s, scratch};

/// Renders the seed scene with `flags`; returns the summary line and the
/// PNG's size.
fn render(name: &str, flags: &str) -> (String, (u32, u32)) {
    let png = scratch("presets", name).join("x.png");
    let summary = run_ok(
        &format!("render res/scenes/seed.toml --threads 2 {flags} -o"),
        &[s(&png)],
    );
    let tex = lucent_assets::texture_from_bytes(&std::fs::read(&png).unwrap(), &png).unwrap();
    (summary, (tex.width(), tex.height()))
}

#[test]
fn preview_is_the_one_pass_preview_and_whitted_keeps_the_report_model() {
    // seed.toml is 640x360 at 4 spp; preview keeps the size, one sample,
    // direct light and one bounce, its reflected light at a quarter size.
    let (summary, size) = render("preview", "--preset preview");
    assert_eq!(size, (640, 360));
    assert!(
        summary.contains("640x360, 1 spp, path max_depth 3, reflected light at 1/4 size"),
        "{summary}"
    );
    let (summary, size) = render("whitted", "--preset whitted");
    assert_eq!(size, (320, 180));
    assert!(summary.contains("320x180, 1 spp, whitted gouraud"), "{summary}");
}

#[test]
fn a_lighting_scale_renders_the_one_pass_preview_at_full_size() {
    let (summary, size) = render("one-pass", "--preset preview --size 64x36 --lighting-scale 4");
    assert_eq!(size, (64, 36));
    assert!(
        summary.contains("64x36, 1 spp, path max_depth 3, reflected light at 1/4 size"),
        "{summary}"
    );
    // The one-pass preview is no set of samples to refine to a clock.
    let png = scratch("presets", "one-pass-budget").join("x.png");
    let err = run_fail(
        1,
        "render res/scenes/seed.toml --lighting-scale 4 --integrator path --time-budget 1s -o",
        &[s(&png)],
    );
    assert!(err.contains("--time-budget with a lighting scale of 4"), "{err}");
}

#[test]
fn interactive_smooths_in_one_pass_unless_told_otherwise() {
    let depth = lucent_render::quality::preset("interactive")
        .unwrap()
        .settings
        .max_depth
        .unwrap();
    let (summary, size) = render("interactive", "--preset interactive --size 64x36");
    assert_eq!(size, (64, 36));
    assert!(
        summary.contains(&format!(
            "64x36, 8 spp, path max_depth {depth}, reflected light smoothed"
        )),
        "{summary}"
    );
    let png = scratch("presets", "interactive-budget").join("x.png");
    let err = run_fail(
        1,
        "render res/scenes/seed.toml --preset interactive --size 64x36 --target-error 0.1 -o",
        &[s(&png)],
    );
    assert!(err.contains("--target-error with smoothing"), "{err}");
    assert!(err.contains("--smooth=false"), "{err}");
    // Turned off, it is plain samples again, which a time budget refines.
    let (summary, _) = render(
        "interactive-plain",
        "--preset interactive --size 64x36 --smooth=false --time-budget 0.2s",
    );
    assert!(!summary.contains("smoothed"), "{summary}");
    assert!(summary.contains(&format!("path max_depth {depth}")), "{summary}");
}

#[test]
fn explicit_flags_win_over_the_preset() {
    let (summary, size) = render("final", "--preset final --size 48x27 --spp 2 --max-depth 3");
    assert_eq!(size, (48, 27));
    assert!(summary.contains("48x27, 2 spp, path max_depth 3"), "{summary}");
    // Without the flags the final preset path traces with its own depth.
    let (summary, _) = render("final-depth", "--preset final --size 16x9 --spp 1");
    let depth = lucent_render::quality::preset("final")
        .unwrap()
        .settings
        .max_depth
        .unwrap();
    assert!(summary.contains(&format!("path max_depth {depth}")), "{summary}");
}

#[test]
fn an_unknown_preset_is_a_usage_error_listing_the_presets() {
    for cmd in ["render res/scenes/seed.toml -o x.png", "bench render", "view"] {
        let err = run_fail(2, &format!("{cmd} --preset ultra"), &[]);
        assert!(
            err.contains("'ultra' is not a preset; the presets are preview, interactive, final, reference, whitted"),
            "{err}"
        );
    }
}

#[test]
fn help_names_the_presets() {
    for cmd in ["render --help", "bench render --help", "view --help"] {
        let help = run_ok(cmd, &[]);
        assert!(help.contains("--preset"), "{cmd:?}: {help}");
        // Each preset on its own line with its description.
        for p in lucent_render::quality::all_presets() {
            assert!(
                help.lines().any(|l| l.contains(p.name) && l.contains(p.description)),
                "{cmd:?} lacks {}: {help}",
                p.name
            );
        }
    }
}
