//! What the viewer reports about each displayed frame: the `--stats` JSON
//! line (read by the window tests and the viewer benchmark) and the title
//! bar, plus the smoothed frame clock both use.

use super::worker::Frame;
use std::fmt::Write as _;

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
    /// One JSON object on one line. Non-finite numbers (which the rig's
    /// sanitising rules out) would print as `null`, never as invalid JSON.
    pub fn json(&self) -> String {
        let f = self.frame;
        let r = &f.rig;
        let num = |x: f64| {
            if x.is_finite() {
                format!("{x:.6}")
            } else {
                "null".to_owned()
            }
        };
        // The radius spans 1e-9 to 1e7: all its digits, not six decimals
        // (which printed the smallest radii as 0).
        let radius = if r.radius.is_finite() {
            format!("{:e}", r.radius)
        } else {
            "null".to_owned()
        };
        let mut s = String::with_capacity(320);
        let _ = write!(
            s,
            "{{\"frame\":{},\"t_s\":{},\"frame_ms\":{},\"render_ms\":{},\"output_ms\":{},\"width\":{},\"height\":{},\"scale\":{},\
\"samples\":{},\"refined\":{},\"moving\":{},\"since_change_ms\":{},\"generation\":{},\"preset\":\"{}\",\
\"shading\":\"{}\",\"denoised\":{},\"denoise_ms\":{},\"camera\":{{\"R\":{},\"theta\":{},\"phi\":{},\"O\":[{},{},{}]}}}}",
            self.index,
            num(self.t_s),
            num(f64::from(self.frame_s) * 1e3),
            num(f64::from(f.render_s) * 1e3),
            num(f64::from(f.output_s) * 1e3),
            f.width,
            f.height,
            num(f64::from(f.scale(self.window_width))),
            f.samples,
            f.refined,
            self.moving,
            num(f64::from(self.since_change_s) * 1e3),
            f.generation,
            self.preset,
            self.shading,
            f.denoised,
            num(f64::from(f.denoise_s) * 1e3),
            radius,
            num(f64::from(r.theta)),
            num(f64::from(r.phi)),
            num(f64::from(r.center.x)),
            num(f64::from(r.center.y)),
            num(f64::from(r.center.z)),
        );
        s
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
        assert!(!line.contains('\n') && !line.contains("NaN") && line.contains("\"frame_ms\":null"));
        for field in [
            "\"frame\":3,",
            "\"render_ms\":20.000000,\"output_ms\":1.000000,",
            "\"width\":320,\"height\":180,\"scale\":2.000000,",
            "\"samples\":1,\"refined\":false,\"moving\":true,",
            "\"generation\":7,",
            "\"denoised\":true,\"denoise_ms\":4.000000,",
            "\"camera\":{\"R\":3e0,\"theta\":0.250000,\"phi\":1.500000,\"O\":[1.000000,-2.000000,0.500000]}}",
        ] {
            assert!(line.contains(field), "{field} in {line}");
        }
        assert_eq!(line.matches('{').count(), line.matches('}').count());
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
