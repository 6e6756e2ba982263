//! Tests of the shared quality flags: `--preset` parsing and its error,
//! which commands take it, and that explicit flags win over the preset.

use super::*;
use clap::error::ErrorKind;
use lucent_render::quality::PRESETS;
use lucent_render::{BuildQuality, RenderSettings};

fn parse(args: &[&str]) -> Result<Cli, clap::Error> {
    Cli::try_parse_from(std::iter::once("lucent").chain(args.iter().copied()))
}

fn quality_of(args: &[&str]) -> QualityArgs {
    match parse(args).map(|cli| cli.command) {
        Ok(Some(Command::Render(a))) => a.quality,
        Ok(Some(Command::View(a))) => a.quality,
        other => panic!("not render or view: {:?}", other.err()),
    }
}

#[test]
fn render_view_and_bench_take_every_preset_by_name() {
    for p in &PRESETS {
        let commands: [&[&str]; 2] = [
            &["render", "s.toml", "-o", "x.png", "--preset", p.name],
            &["view", "--preset", p.name],
        ];
        for args in commands {
            assert_eq!(quality_of(args).preset, Some(p), "{args:?}");
        }
        // `bench render` flattens the same arguments.
        let bench = parse(&["bench", "render", "--preset", p.name]);
        assert!(
            matches!(
                bench,
                Ok(Cli {
                    command: Some(Command::Bench(_)),
                    ..
                })
            ),
            "{}",
            p.name
        );
    }
    assert!(parse(&["bench", "render", "--preset", "ultra"]).is_err());
    assert_eq!(quality_of(&["view"]).preset, None);
}

#[test]
fn an_unknown_preset_is_a_usage_error_listing_the_names() {
    for bad in ["ultra", "Final", "1", ""] {
        let err = match parse(&["render", "s.toml", "-o", "x.png", "--preset", bad]) {
            Ok(_) => panic!("{bad:?} parsed"),
            Err(e) => e,
        };
        assert_eq!(err.kind(), ErrorKind::ValueValidation, "{bad:?}");
        let text = err.to_string();
        assert!(text.contains("--preset"), "{text}");
        assert!(
            text.contains(&format!(
                "'{bad}' is not a preset; the presets are preview, interactive, final, reference"
            )),
            "{text}"
        );
    }
}

#[test]
fn explicit_flags_override_the_preset() {
    let preview = &PRESETS[0];
    let scene = |q: &QualityArgs| {
        let mut scene = Scene {
            settings: RenderSettings {
                width: 640,
                height: 360,
                seed: 9,
                ..RenderSettings::default()
            },
            ..Scene::default()
        };
        q.apply(&mut scene);
        scene.settings
    };
    // The preset alone: scaled scene size and every preset field.
    let s = scene(&quality_of(&["view", "--preset", "preview"]));
    let mut want = RenderSettings {
        width: 640,
        height: 360,
        seed: 9,
        ..RenderSettings::default()
    };
    preview.apply(&mut want);
    assert_eq!(s, want);
    assert_eq!((s.width, s.height, s.lighting_scale, s.smooth), (640, 360, 4, true));
    // Each flag wins over the preset, whatever the order on the line.
    for args in [
        ["view", "--preset", "preview", "--size", "100x50", "--max-depth", "7"],
        ["view", "--size", "100x50", "--max-depth", "7", "--preset", "preview"],
    ] {
        let s = scene(&quality_of(&args));
        assert_eq!((s.width, s.height, s.max_depth), (100, 50, 7), "{args:?}");
        assert_eq!(
            (Some(s.spp), Some(s.shading), Some(s.integrator)),
            (
                preview.settings.spp,
                preview.settings.shading,
                preview.settings.integrator
            )
        );
    }
    let s = scene(&quality_of(&[
        "view",
        "--preset",
        "reference",
        "--integrator",
        "whitted",
        "--shading",
        "gouraud",
        "--rr-depth",
        "3",
        "--min-weight",
        "0.5",
        "--seed",
        "4",
    ]));
    assert_eq!(
        (s.integrator, s.shading, s.rr_depth, s.min_weight, s.seed),
        (Integrator::Whitted, Shading::Gouraud, 3, 0.5, 4)
    );
    assert_eq!(
        (Some(s.spp), Some(s.max_depth)),
        (PRESETS[3].settings.spp, PRESETS[3].settings.max_depth)
    );
    // No preset: the scene's own settings under the flags.
    let s = scene(&quality_of(&["view", "--max-depth", "2"]));
    assert_eq!((s.width, s.height, s.max_depth, s.spp), (640, 360, 2, 1));
    // `--smooth` alone turns smoothing on, `--smooth=false` off (over the
    // interactive preset's), and takes no value from the next word.
    assert_eq!(quality_of(&["view", "--smooth"]).smooth, Some(true));
    let s = scene(&quality_of(&["view", "--preset", "interactive", "--smooth=false"]));
    assert!(!s.smooth && !s.one_pass());
    assert!(scene(&quality_of(&["view", "--preset", "interactive"])).one_pass());
    let q = quality_of(&["render", "--smooth", "s.toml", "-o", "x.png"]);
    assert_eq!(q.smooth, Some(true));
    assert!(parse(&["view", "--smooth=maybe"]).is_err());
    // `--lanes` works the same way, and reaches the settings; the lanes
    // are on unless asked off.
    assert!(scene(&quality_of(&["render", "--lanes", "s.toml", "-o", "x.png"])).lanes);
    assert!(!scene(&quality_of(&["render", "--lanes=false", "s.toml", "-o", "x.png"])).lanes);
    assert!(scene(&quality_of(&["render", "s.toml", "-o", "x.png"])).lanes);
    assert!(parse(&["render", "--lanes=sometimes", "s.toml", "-o", "x.png"]).is_err());
}

#[test]
fn spp_flag_overrides_the_preset_and_the_build_quality_follows_it() {
    let q = quality_of(&["render", "s.toml", "-o", "x.png", "--preset", "final"]);
    let (scene, _, _) = prepare_scene(None, &q, None).unwrap();
    assert_eq!(Some(scene.settings.spp), PRESETS[2].settings.spp);
    let (scene, _, _) = prepare_scene(None, &q, Some(3)).unwrap();
    assert_eq!(scene.settings.spp, 3);
    assert_eq!(q.extract_options().bvh_quality, PRESETS[2].bvh_quality);
    assert_eq!(
        quality_of(&["view", "--preset", "preview"])
            .extract_options()
            .bvh_quality,
        BuildQuality::Fast
    );
    assert_eq!(quality_of(&["view"]).extract_options(), ExtractOptions::default());
}
