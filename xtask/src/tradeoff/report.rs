//! What the tradeoff measured, the monotone check, and the Markdown and TSV
//! reports written from it.

use lucent_render::metrics::ImageError;
use std::fmt::Write as _;

/// Timing of one render of a preset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Extract, BVH builds included (seconds).
    pub extract_s: f64,
    /// Tracing (seconds).
    pub render_s: f64,
    /// Denoising (seconds; 0 for a rung that does not denoise).
    pub denoise_s: f64,
}

impl Timing {
    /// Extract plus render plus denoise.
    pub fn total(&self) -> f64 {
        self.extract_s + self.render_s + self.denoise_s
    }
}

/// Which curve a row belongs to: the monotone check runs along each of the
/// first two separately.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Series {
    /// The physical ladder, as rendered.
    Ladder,
    /// The same rungs denoised (OIDN, albedo and normal).
    Denoised,
    /// Off the ladder (the report's Whitted model), shown for comparison.
    Other,
}

/// One preset on one scene.
#[derive(Clone, Debug)]
pub struct PresetResult {
    /// Row name (the preset's, `+oidn` when denoised).
    pub name: String,
    /// The curve it is on.
    pub series: Series,
    /// Its settings, one line.
    pub settings: String,
    /// Every run.
    pub runs: Vec<Timing>,
    /// Error against the reference, after upsampling.
    pub error: ImageError,
    /// Mean LDR-FLIP.
    pub flip: f64,
}

pub(crate) use lucent_render::metrics::median;

impl PresetResult {
    /// Median of extract + render.
    pub fn time(&self) -> f64 {
        median(&mut self.runs.iter().map(Timing::total).collect::<Vec<_>>())
    }

    /// Median extract time.
    pub fn extract_time(&self) -> f64 {
        median(&mut self.runs.iter().map(|t| t.extract_s).collect::<Vec<_>>())
    }

    /// Median render time.
    pub fn render_time(&self) -> f64 {
        median(&mut self.runs.iter().map(|t| t.render_s).collect::<Vec<_>>())
    }

    /// Median denoise time.
    pub fn denoise_time(&self) -> f64 {
        median(&mut self.runs.iter().map(|t| t.denoise_s).collect::<Vec<_>>())
    }

    /// Fastest and slowest run (extract + render).
    pub fn spread(&self) -> (f64, f64) {
        let t: Vec<f64> = self.runs.iter().map(Timing::total).collect();
        (
            t.iter().copied().fold(f64::INFINITY, f64::min),
            t.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    }
}

/// The reference of one scene, as the report shows it.
#[derive(Clone, Debug)]
pub struct ReferenceSummary {
    /// How it was rendered, one line.
    pub describe: String,
    /// Its own estimated RMSE.
    pub noise_rmse: f64,
    /// Its render time (seconds), when it was rendered.
    pub render_s: f64,
    /// Whether this run took it from the cache.
    pub cached: bool,
    /// Cache key.
    pub key: String,
    /// Whether the renderer's sources changed since its batches were
    /// rendered (their probe matched, so they were kept).
    pub sources_changed: bool,
}

/// One scene's results.
#[derive(Clone, Debug)]
pub struct SceneResult {
    /// Scene file as given.
    pub scene: String,
    /// File stem, used in output names.
    pub stem: String,
    /// The reference.
    pub reference: ReferenceSummary,
    /// Presets, in table order.
    pub presets: Vec<PresetResult>,
}

/// Where and how the run happened.
#[derive(Clone, Debug, Default)]
pub struct RunInfo {
    /// UTC date and time.
    pub date: String,
    /// `git describe`-like commit.
    pub commit: String,
    /// CPU model.
    pub cpu: String,
    /// Logical CPUs.
    pub cores: usize,
    /// Render threads.
    pub threads: usize,
    /// The command line.
    pub command: String,
    /// Runs per preset.
    pub runs: usize,
    /// `/proc/loadavg` before the timed runs.
    pub load_before: String,
    /// And after.
    pub load_after: String,
}

/// A step of the curve that is not more accurate than the faster step
/// before it.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// The faster preset.
    pub faster: String,
    /// The slower one, which should have had the lower error.
    pub slower: String,
    /// Their errors.
    pub errors: (f64, f64),
}

/// Checks that error falls strictly as time grows: orders the points
/// `(name, time, error)` by time and returns every consecutive pair whose
/// slower point does not have the lower error. Empty means monotone.
pub fn monotone_violations(points: &[(&str, f64, f64)]) -> Vec<Violation> {
    let mut sorted: Vec<&(&str, f64, f64)> = points.iter().collect();
    sorted.sort_by(|a, b| a.1.total_cmp(&b.1));
    sorted
        .windows(2)
        .filter(|w| w[1].2.partial_cmp(&w[0].2) != Some(std::cmp::Ordering::Less))
        .map(|w| Violation {
            faster: w[0].0.to_owned(),
            slower: w[1].0.to_owned(),
            errors: (w[0].2, w[1].2),
        })
        .collect()
}

impl SceneResult {
    /// Violations along each curve (ladder, denoised ladder) of `value`.
    fn violations(&self, value: fn(&PresetResult) -> f64) -> Vec<Violation> {
        [Series::Ladder, Series::Denoised]
            .into_iter()
            .flat_map(|series| {
                let pts: Vec<(&str, f64, f64)> = self
                    .presets
                    .iter()
                    .filter(|p| p.series == series)
                    .map(|p| (p.name.as_str(), p.time(), value(p)))
                    .collect();
                monotone_violations(&pts)
            })
            .collect()
    }

    /// Violations of the RMSE curves (the primary measure).
    pub fn rmse_violations(&self) -> Vec<Violation> {
        self.violations(|p| p.error.rmse)
    }

    /// Violations of the FLIP curves.
    pub fn flip_violations(&self) -> Vec<Violation> {
        self.violations(|p| p.flip)
    }

    /// The row called `name`.
    pub fn row(&self, name: &str) -> Option<&PresetResult> {
        self.presets.iter().find(|p| p.name == name)
    }

    /// The two goals on this scene, one line each, for the rows
    /// measured: denoised `interactive` against plain `final` (RMSE and
    /// FLIP), and `preview` against the Whitted preview it replaced (at
    /// most half the RMSE in at most twice the time).
    pub fn goals(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let (Some(dn), Some(fin)) = (self.row("interactive+oidn"), self.row("final")) {
            let met = dn.error.rmse <= fin.error.rmse && dn.flip <= fin.flip;
            out.push(format!(
                "denoised interactive against final: RMSE {} vs {}, FLIP {} vs {}, time {} s vs {} s: {}",
                sig(dn.error.rmse, 4),
                sig(fin.error.rmse, 4),
                sig(dn.flip, 3),
                sig(fin.flip, 3),
                sig(dn.time(), 3),
                sig(fin.time(), 3),
                if met { "met" } else { "**not met**" }
            ));
        }
        if let (Some(pv), Some(wh)) = (self.row("preview"), self.row("whitted")) {
            let (e, t) = (pv.error.rmse / wh.error.rmse, pv.time() / wh.time());
            out.push(format!(
                "preview against the Whitted preview: RMSE {} vs {} (x{}, goal at most x0.5), time {} s vs {} s (x{}, goal at most x2): {}",
                sig(pv.error.rmse, 4),
                sig(wh.error.rmse, 4),
                sig(e, 3),
                sig(pv.time(), 3),
                sig(wh.time(), 3),
                sig(t, 3),
                if e <= 0.5 && t <= 2.0 { "met" } else { "**not met**" }
            ));
        }
        out
    }

    /// Names in order of median time, when that differs from table order.
    pub fn time_order(&self) -> Vec<&str> {
        let mut v: Vec<&PresetResult> = self.presets.iter().collect();
        v.sort_by(|a, b| a.time().total_cmp(&b.time()));
        v.iter().map(|p| p.name.as_str()).collect()
    }
}

/// `x` with `n` significant digits (plain notation).
pub fn sig(x: f64, n: i32) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_owned();
    }
    let decimals = (n - 1 - x.abs().log10().floor() as i32).max(0);
    format!("{x:.*}", decimals as usize)
}

fn verdict(v: &[Violation]) -> String {
    if v.is_empty() {
        return "yes".to_owned();
    }
    let steps: Vec<String> = v
        .iter()
        .map(|v| {
            format!(
                "{} ({}) is slower than {} ({}) but not more accurate",
                v.slower,
                sig(v.errors.1, 4),
                v.faster,
                sig(v.errors.0, 4)
            )
        })
        .collect();
    format!("**no**: {}", steps.join("; "))
}

/// The Markdown report.
pub fn markdown(info: &RunInfo, scenes: &[SceneResult], plot: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Speed against accuracy\n");
    let _ = writeln!(s, "Command: `{}`  ", info.command);
    let _ = writeln!(s, "Date: {}; commit {}  ", info.date, info.commit);
    let _ = writeln!(
        s,
        "Machine: {} ({} logical CPUs), {} render threads; load average before the timed runs {}, after {}\n",
        info.cpu, info.cores, info.threads, info.load_before, info.load_after
    );
    let _ = writeln!(
        s,
        "Each preset is rendered {} times, the presets taking turns (preset 1, 2, ... then again), \
         in the release build. Time is the median wall time of extract (BVH builds included) plus \
         render; the spread is the fastest and slowest run. Errors are against the converged \
         reference, on linear radiance: RMSE, relative RMSE (RMSE over the reference's mean) and \
         PSNR (peak 1), as `lucent_render::metrics` defines them; FLIP is the mean LDR-FLIP \
         (nv-flip, 67 pixels per degree) of the 8-bit sRGB images at exposure 0. A preset rendered \
         below the reference's size is upsampled to it bilinearly (between pixel centres, edges \
         clamped) before it is compared. The curve is monotone when every slower preset has a lower \
         error; RMSE is the primary measure (relative RMSE and PSNR order the same way).\n",
        info.runs
    );
    for sc in scenes {
        let _ = writeln!(s, "## {} (`{}`)\n", sc.stem, sc.scene);
        let r = &sc.reference;
        let best = sc.presets.iter().map(|p| p.error.rmse).fold(f64::INFINITY, f64::min);
        // Independent noise adds in quadrature: a measured e is
        // sqrt(true^2 + noise^2), so the best preset's is high by this much.
        let inflation = 1.0 - (best * best - r.noise_rmse * r.noise_rmse).max(0.0).sqrt() / best;
        let _ = writeln!(
            s,
            "Reference: {}; {} ({} s to render); cache key `{}`. Its own noise (standard error \
             of its batches' mean): RMSE {}, {}x below the best preset's RMSE {} (which it raises \
             by {}%, as independent errors add in quadrature).\n",
            r.describe,
            match (r.cached, r.sources_changed) {
                (true, false) => "from the cache",
                (true, true) => "from the cache (the renderer's sources changed since, its probe did not)",
                (false, _) => "rendered by this run (or partly)",
            },
            sig(r.render_s, 3),
            r.key,
            sig(r.noise_rmse, 3),
            sig(best / r.noise_rmse, 3),
            sig(best, 4),
            sig(100.0 * inflation, 2),
        );
        let _ = writeln!(
            s,
            "| preset | settings | time (s) | extract + render (+ denoise) (s) | spread (s) | RMSE | rel. RMSE | PSNR (dB) | FLIP |"
        );
        let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|---:|---:|");
        for p in &sc.presets {
            let (lo, hi) = p.spread();
            let denoise = if p.series == Series::Denoised {
                format!(" + {}", sig(p.denoise_time(), 3))
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} + {}{denoise} | {} to {} | {} | {} | {:.2} | {} |",
                p.name,
                p.settings,
                sig(p.time(), 3),
                sig(p.extract_time(), 2),
                sig(p.render_time(), 3),
                sig(lo, 3),
                sig(hi, 3),
                sig(p.error.rmse, 4),
                sig(p.error.relative_rmse, 4),
                p.error.psnr,
                sig(p.flip, 3),
            );
        }
        let order = sc.time_order();
        let table: Vec<&str> = sc.presets.iter().map(|p| p.name.as_str()).collect();
        let _ = writeln!(s);
        if order != table {
            let _ = writeln!(s, "Measured order by time: {}.  ", order.join(", "));
        }
        let _ = writeln!(
            s,
            "Monotone in RMSE (the ladder, and the denoised ladder, each on its own): {}.  ",
            verdict(&sc.rmse_violations())
        );
        let _ = writeln!(s, "Monotone in FLIP: {}.\n", verdict(&sc.flip_violations()));
        for g in sc.goals() {
            let _ = writeln!(s, "- Goal: {g}");
        }
        if !sc.goals().is_empty() {
            let _ = writeln!(s);
        }
        let _ = writeln!(s, "![contact sheet of {0}]({0}-contact.png)\n", sc.stem);
    }
    let _ = writeln!(s, "![error against time]({plot})");
    s
}

/// One line per (scene, preset), tab-separated, for scripts.
pub fn tsv(scenes: &[SceneResult]) -> String {
    let mut s = String::from(
        "scene\tpreset\tsettings\ttime_s\textract_s\trender_s\tdenoise_s\tmin_s\tmax_s\trmse\trel_rmse\tpsnr_db\tflip\tref_noise_rmse\n",
    );
    for sc in scenes {
        for p in &sc.presets {
            let (lo, hi) = p.spread();
            let _ = writeln!(
                s,
                "{}\t{}\t{}\t{:.6}\t{:.6}\t{:.6}\t{:.6}\t{:.6}\t{:.6}\t{:.6}\t{:.6}\t{:.4}\t{:.6}\t{:.6}",
                sc.stem,
                p.name,
                p.settings,
                p.time(),
                p.extract_time(),
                p.render_time(),
                p.denoise_time(),
                lo,
                hi,
                p.error.rmse,
                p.error.relative_rmse,
                p.error.psnr,
                p.flip,
                sc.reference.noise_rmse
            );
        }
    }
    s
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn preset(name: &str, times: &[f64], rmse: f64, flip: f64) -> PresetResult {
        PresetResult {
            name: name.to_owned(),
            series: Series::Ladder,
            settings: format!("{name} settings"),
            runs: times
                .iter()
                .map(|t| Timing {
                    extract_s: 0.1 * t,
                    render_s: 0.9 * t,
                    denoise_s: 0.0,
                })
                .collect(),
            error: ImageError {
                rmse,
                relative_rmse: rmse * 2.0,
                psnr: lucent_render::metrics::psnr_from_rmse(rmse),
            },
            flip,
        }
    }

    pub(crate) fn scene(presets: Vec<PresetResult>) -> SceneResult {
        SceneResult {
            scene: "res/scenes/tiny.toml".to_owned(),
            stem: "tiny".to_owned(),
            reference: ReferenceSummary {
                describe: "path tracer, 4x2, 64 spp".to_owned(),
                noise_rmse: 0.001,
                render_s: 12.0,
                cached: true,
                key: "0123456789abcdef".to_owned(),
                sources_changed: false,
            },
            presets,
        }
    }

    #[test]
    fn medians_and_spread() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&mut []).is_nan());
        let p = preset("p", &[2.0, 1.0, 4.0], 0.1, 0.2);
        assert!((p.time() - 2.0).abs() < 1e-12);
        assert!((p.extract_time() - 0.2).abs() < 1e-12 && (p.render_time() - 1.8).abs() < 1e-12);
        assert_eq!(p.spread(), (1.0, 4.0));
    }

    #[test]
    fn monotone_check_orders_by_time() {
        assert!(monotone_violations(&[("a", 1.0, 0.5), ("b", 2.0, 0.2), ("c", 3.0, 0.1)]).is_empty());
        // Table order does not matter, measured time does.
        assert!(monotone_violations(&[("c", 3.0, 0.1), ("a", 1.0, 0.5), ("b", 2.0, 0.2)]).is_empty());
        let v = monotone_violations(&[("a", 1.0, 0.5), ("b", 2.0, 0.6), ("c", 3.0, 0.1)]);
        assert_eq!(
            v,
            vec![Violation {
                faster: "a".to_owned(),
                slower: "b".to_owned(),
                errors: (0.5, 0.6)
            }]
        );
        // Equal error is not an improvement; NaN never is.
        assert_eq!(monotone_violations(&[("a", 1.0, 0.5), ("b", 2.0, 0.5)]).len(), 1);
        assert_eq!(monotone_violations(&[("a", 1.0, 0.5), ("b", 2.0, f64::NAN)]).len(), 1);
        assert!(monotone_violations(&[]).is_empty());
    }

    #[test]
    fn report_has_a_row_per_preset_and_the_verdicts() {
        let good = scene(vec![
            preset("fast", &[0.1, 0.12, 0.11], 0.2, 0.3),
            preset("slow", &[1.0, 1.1, 0.9], 0.05, 0.1),
        ]);
        let mut bad = scene(vec![
            preset("fast", &[0.1, 0.12, 0.11], 0.2, 0.3),
            preset("slow", &[1.0, 1.1, 0.9], 0.25, 0.1),
        ]);
        bad.stem = "bad".to_owned();
        let info = RunInfo {
            command: "cargo xtask tradeoff tiny.toml".to_owned(),
            runs: 3,
            ..RunInfo::default()
        };
        let md = markdown(&info, &[good.clone(), bad.clone()], "tradeoff.png");
        assert!(md.contains("`cargo xtask tradeoff tiny.toml`"), "{md}");
        assert!(
            md.contains(
                "| fast | fast settings | 0.110 | 0.011 + 0.0990 | 0.100 to 0.120 | 0.2000 | 0.4000 | 13.98 | 0.300 |"
            ),
            "{md}"
        );
        assert!(md.contains("| slow | slow settings | 1.00 |"), "{md}");
        assert!(md.contains("each on its own): yes."), "{md}");
        assert!(
            md.contains("each on its own): **no**: slow (0.2500) is slower than fast (0.2000)"),
            "{md}"
        );
        assert!(
            md.contains("RMSE 0.00100, 50.0x below the best preset's RMSE 0.05000 (which it raises by 0.020%"),
            "{md}"
        );
        assert!(md.contains("![contact sheet of bad](bad-contact.png)"), "{md}");
        assert!(good.rmse_violations().is_empty() && bad.rmse_violations().len() == 1);
        let t = tsv(&[good]);
        assert_eq!(t.lines().count(), 3);
        assert!(
            t.lines()
                .nth(1)
                .is_some_and(|l| l.starts_with("tiny\tfast\tfast settings\t0.110000\t")),
            "{t}"
        );
    }

    #[test]
    fn each_curve_is_checked_on_its_own_and_the_goals_are_judged() {
        let mut dn = preset("interactive+oidn", &[0.5], 0.04, 0.08);
        dn.series = Series::Denoised;
        let mut fin_dn = preset("final+oidn", &[4.0], 0.02, 0.05);
        fin_dn.series = Series::Denoised;
        let mut whitted = preset("whitted", &[0.05], 0.25, 0.4);
        whitted.series = Series::Other;
        let sc = scene(vec![
            preset("preview", &[0.08], 0.1, 0.3),
            preset("interactive", &[0.4], 0.06, 0.1),
            preset("final", &[3.0], 0.05, 0.09),
            dn.clone(),
            fin_dn,
            whitted,
        ]);
        // interactive+oidn beats the slower plain final: not a violation,
        // the curves are separate; nor is whitted, which is off both.
        assert!(sc.rmse_violations().is_empty(), "{:?}", sc.rmse_violations());
        let goals = sc.goals();
        assert_eq!(goals.len(), 2, "{goals:?}");
        assert!(
            goals[0].starts_with("denoised interactive against final: RMSE 0.04000 vs 0.05000"),
            "{goals:?}"
        );
        assert!(goals[0].ends_with(": met"), "{goals:?}");
        // 0.1 / 0.25 = 0.4 in 0.08 / 0.05 = 1.6 times the time.
        assert!(goals[1].contains("(x0.400, goal at most x0.5)"), "{goals:?}");
        assert!(
            goals[1].contains("(x1.60, goal at most x2)") && goals[1].ends_with(": met"),
            "{goals:?}"
        );
        let mut slow = sc.clone();
        slow.presets[0] = preset("preview", &[0.2], 0.1, 0.3);
        assert!(slow.goals()[1].ends_with("**not met**"));
        // A denoised rung that is slower but worse is a violation.
        let mut bad = sc;
        bad.presets[4].error.rmse = 0.05;
        assert_eq!(bad.rmse_violations().len(), 1);
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.012345, 3), "0.0123");
        assert_eq!(sig(12.345, 3), "12.3");
        assert_eq!(sig(1234.4, 3), "1234");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(f64::INFINITY, 3), "inf");
    }
}
