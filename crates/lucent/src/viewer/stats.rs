//! What the viewer reports about each displayed frame: the `--stats` JSON
//! line (read by the window tests and the viewer benchmark) and the title
//! bar, plus the smoothed frame clock both use.

use super::worker::Frame;

/// One displayed frame, as `--stats` prints it.
pub struct FrameReport<'a> {
    /// Displayed frames so far, this one included.
    pub index: u64,
    /// Seconds since the viewer started.
    pub t_s: f64,
    /// Seconds since the previous displayed frame.
    pub frame_s: f32,
    /// The frame.
    pub frame: &'a Frame,
    /// Window width (the frame's scale is relative to it).
    pub window_width: u32,
    /// The camera is moving (the latest input changed it).
    pub moving: bool,
    /// Seconds since the camera or settings last changed.
    pub since_change_s: f32,
    /// Quality preset name.
    pub preset: &'static str,
    /// Shading name.
    pub shading: &'static str,
}

impl FrameReport<'_> {
    /// One JSON object on one line, through serde_json: non-finite
    /// numbers (which the rig's sanitising rules out) print as `null`.
    pub fn json(&self) -> String {
        let f = self.frame;
        let r = &f.rig;
        serde_json::json!({
            "frame": self.index,
            "t_s": self.t_s,
            "frame_ms": f64::from(self.frame_s) * 1e3,
            "render_ms": f64::from(f.render_s) * 1e3,
            "output_ms": f64::from(f.output_s) * 1e3,
            "width": f.width,
            "height": f.height,
            "scale": f.scale(self.window_width),
            "samples": f.samples,
            "refined": f.refined,
            "moving": self.moving,
            "since_change_ms": f64::from(self.since_change_s) * 1e3,
            "generation": f.generation,
            "preset": self.preset,
            "shading": self.shading,
            "denoised": f.denoised,
            "denoise_ms": f64::from(f.denoise_s) * 1e3,
            "camera": { "R": r.radius, "theta": r.theta, "phi": r.phi, "O": r.center.to_array() },
        })
        .to_string()
    }
}

/// Smoothed displayed-frame rate for the title bar.
#[derive(Default)]
pub struct FrameClock {
    avg_s: f32,
}

impl FrameClock {
    /// Records a frame `dt` seconds after the previous one.
    pub fn tick(&mut self, dt: f32) {
        self.avg_s = if self.avg_s == 0.0 {
            dt
        } else {
            0.9 * self.avg_s + 0.1 * dt
        };
    }

    /// Frames per second.
    pub fn fps(&self) -> f32 {
        if self.avg_s > 0.0 { 1.0 / self.avg_s } else { 0.0 }
    }

    /// Milliseconds per frame.
    pub fn frame_ms(&self) -> f32 {
        1000.0 * self.avg_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Vec3;
    use lucent_scene::components::OrbitRig;

    #[test]
    fn json_line_has_every_field_and_no_bare_nan() {
        let frame = Frame {
            generation: 7,
            rig: OrbitRig {
                center: Vec3::new(1.0, -2.0, 0.5),
                radius: 3.0,
                theta: 0.25,
                phi: 1.5,
            },
            pixels: Vec::new(),
            width: 320,
            height: 180,
            samples: 1,
            refined: false,
            render_s: 0.02,
            output_s: 0.001,
            denoise_s: 0.004,
            denoised: true,
            denoise_follows: false,
        };
        let report = FrameReport {
            index: 3,
            t_s: 1.5,
            frame_s: f32::NAN,
            frame: &frame,
            window_width: 640,
            moving: true,
            since_change_s: 0.004,
            preset: "interactive",
            shading: "gouraud",
        };
        let line = report.json();
        assert!(!line.contains('\n') && !line.contains("NaN"), "{line}");
        let v: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("{e}: {line}"));
        assert_eq!(v["frame_ms"], serde_json::Value::Null);
        let want = serde_json::json!({
            "frame": 3, "t_s": 1.5, "frame_ms": null, "width": 320, "height": 180, "scale": 2.0,
            "samples": 1, "refined": false, "moving": true, "generation": 7,
            "preset": "interactive", "shading": "gouraud", "denoised": true,
            "camera": { "R": 3.0, "theta": 0.25, "phi": 1.5, "O": [1.0, -2.0, 0.5] },
        });
        for (key, value) in want.as_object().into_iter().flatten() {
            assert_eq!(&v[key], value, "{key} in {line}");
        }
        for (key, ms) in [
            ("render_ms", 20.0),
            ("output_ms", 1.0),
            ("since_change_ms", 4.0),
            ("denoise_ms", 4.0),
        ] {
            assert!(
                v[key].as_f64().is_some_and(|x| (x - ms).abs() < 1e-3),
                "{key} in {line}"
            );
        }
    }

    #[test]
    fn frame_clock_smooths() {
        let mut c = FrameClock::default();
        assert_eq!(c.fps(), 0.0);
        c.tick(0.05);
        assert!((c.fps() - 20.0).abs() < 1e-3);
        for _ in 0..200 {
            c.tick(0.025);
        }
        assert!((c.frame_ms() - 25.0).abs() < 0.01);
    }
}
