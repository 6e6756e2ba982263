//! Quality presets the viewer switches between with F1-F4 or 1-4: plain
//! settings for the frame budget while moving, the coarsest preview and the
//! sample cap while still. No logic beyond picking one.

/// One quality preset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// Shown in the title and in `--stats`.
    pub name: &'static str,
    /// Frames per second aimed for while the camera moves; the preview's
    /// resolution and samples are sized so a frame fits in `1 / target_fps`.
    pub target_fps: f32,
    /// Coarsest preview: at most this many window pixels per rendered pixel
    /// along each axis.
    pub max_scale: f32,
    /// Samples per pixel accumulated at full resolution while still.
    pub max_spp: u32,
    /// Recursion depth cap (`None`: the scene's own).
    pub max_depth: Option<u32>,
}

/// The presets, in key order (F1/1 first).
pub const PRESETS: [Preset; 4] = [
    Preset {
        name: "draft",
        target_fps: 60.0,
        max_scale: 8.0,
        max_spp: 1,
        max_depth: Some(1),
    },
    Preset {
        name: "interactive",
        target_fps: 40.0,
        max_scale: 6.0,
        max_spp: 64,
        max_depth: None,
    },
    Preset {
        name: "quality",
        target_fps: 20.0,
        max_scale: 4.0,
        max_spp: 256,
        max_depth: None,
    },
    Preset {
        name: "final",
        target_fps: 8.0,
        max_scale: 2.0,
        max_spp: 1024,
        max_depth: None,
    },
];

/// The preset the viewer starts with (index into [`PRESETS`]).
pub const DEFAULT_PRESET: usize = 1;

impl Preset {
    /// The time one frame may take while moving, seconds.
    pub fn frame_budget_s(&self) -> f32 {
        1.0 / self.target_fps.max(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_trade_speed_for_quality_in_key_order() {
        for pair in PRESETS.windows(2) {
            assert!(pair[0].target_fps > pair[1].target_fps, "{pair:?}");
            assert!(pair[0].max_spp < pair[1].max_spp, "{pair:?}");
            assert!(pair[0].max_scale >= pair[1].max_scale, "{pair:?}");
        }
        assert!(PRESETS.iter().all(|p| p.max_scale >= 1.0 && p.frame_budget_s() > 0.0));
        assert_eq!(PRESETS[DEFAULT_PRESET].name, "interactive");
    }
}
