//! The viewer's quality keys: F1-F4 or 1-4 pick lucent-render's four
//! presets ([`PRESETS`]: samples, depth, integrator, shading, roulette and
//! resolution scale come from there). The viewer adds only how a preset
//! behaves while the camera moves ([`Motion`]: the frame rate aimed for and
//! the coarsest preview), in a table kept in the same order. Until a preset
//! is picked the viewer shows the scene's own `[render]` settings, moving
//! as [`SCENE`] says. No logic beyond picking one.

pub use lucent_render::quality::PRESETS;

/// What a preset means to the viewer while the camera moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// The name of the [`PRESETS`] entry this row belongs to.
    pub preset: &'static str,
    /// Frames per second aimed for while the camera moves; the preview's
    /// resolution and samples are sized so a frame fits in `1 / target_fps`.
    pub target_fps: f32,
    /// Coarsest preview: at most this many window pixels per rendered pixel
    /// along each axis.
    pub max_scale: f32,
}

/// Motion parameters of each preset, in the order of [`PRESETS`] (the key
/// order, F1/1 first).
pub const MOTION: [Motion; PRESETS.len()] = [
    Motion {
        preset: "preview",
        target_fps: 60.0,
        max_scale: 8.0,
    },
    Motion {
        preset: "interactive",
        target_fps: 40.0,
        max_scale: 6.0,
    },
    Motion {
        preset: "final",
        target_fps: 20.0,
        max_scale: 4.0,
    },
    Motion {
        preset: "reference",
        target_fps: 8.0,
        max_scale: 2.0,
    },
];

/// How the viewer moves before a preset is picked, on the scene's own
/// settings (named `scene` in the title and `--stats`).
pub const SCENE: Motion = Motion {
    preset: "scene",
    target_fps: 40.0,
    max_scale: 6.0,
};

impl Motion {
    /// The time one frame may take while moving, seconds.
    pub fn frame_budget_s(&self) -> f32 {
        1.0 / self.target_fps.max(1.0)
    }
}

/// The index of the preset called `name` in [`PRESETS`] (and [`MOTION`]).
pub fn index_of(name: &str) -> Option<usize> {
    PRESETS.iter().position(|p| p.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_rows_follow_the_shared_presets() {
        for (m, p) in MOTION.iter().zip(&PRESETS) {
            assert_eq!(m.preset, p.name);
            assert_eq!(index_of(p.name).map(|i| PRESETS[i].name), Some(p.name));
        }
        assert_eq!(index_of("draft"), None);
        assert_eq!(index_of(SCENE.preset), None, "the scene's settings are not a preset");
    }

    #[test]
    fn presets_trade_speed_for_quality_in_key_order() {
        for (pair, motion) in PRESETS.windows(2).zip(MOTION.windows(2)) {
            assert!(motion[0].target_fps > motion[1].target_fps, "{motion:?}");
            assert!(motion[0].max_scale >= motion[1].max_scale, "{motion:?}");
            assert!(
                pair[0].settings.spp < pair[1].settings.spp,
                "{} {}",
                pair[0].name,
                pair[1].name
            );
        }
        assert!(
            MOTION
                .iter()
                .chain([&SCENE])
                .all(|m| m.max_scale >= 1.0 && m.frame_budget_s() > 0.0)
        );
        // The coarsest preview is never finer than the still image.
        for (m, p) in MOTION.iter().zip(&PRESETS) {
            assert!(m.max_scale * p.resolution_scale >= 1.0, "{}", p.name);
        }
    }
}
