//! `lucent render --time-budget` and `--target-error` end to end: what they
//! print, that their output does not depend on the thread count, and their
//! errors on bad values.

mod common;

use common::{run_fail, run_ok, s, scratch};
use std::path::Path;

/// Runs `lucent render` on the Cornell box at 32x32 with `flags` and the
/// output `path`; returns stdout.
fn render(flags: &str, path: &Path) -> String {
    run_ok(
        &format!("render res/scenes/cornell-mitsuba.toml --size 32x32 {flags}"),
        &[s(path)],
    )
}

/// The number after `key` in `line`.
fn number_after(line: &str, key: &str) -> f64 {
    let at = line.find(key).unwrap_or_else(|| panic!("no '{key}' in {line}")) + key.len();
    let text: String = line[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-' || *c == '+')
        .collect();
    text.parse()
        .unwrap_or_else(|_| panic!("no number after '{key}' in {line}"))
}

/// A 1 s budget: the summary says how many spp it reached and how long it
/// took; the render (after loading and the BVH, which the budget does not
/// cover) must end within 10% of the budget, as the library's own test
/// checks in detail.
#[test]
fn a_time_budget_reports_the_spp_reached_and_keeps_to_the_budget() {
    let dir = scratch("budget", "time");
    let png = dir.join("t.png");
    let line = render("--time-budget 1s -o", &png);
    assert!(png.exists());
    let spp = number_after(&line, "time budget 1 s: ");
    let elapsed = number_after(&line, "samples, ");
    assert!(spp >= 2.0, "{line}");
    assert!((0.9..=1.1).contains(&elapsed), "{line}");
    assert_eq!(number_after(&line, "reached, "), spp * 32.0 * 32.0, "{line}");
}

/// The spp cap: `--spp 2` ends a long budget at two samples per pixel.
#[test]
fn spp_caps_a_time_budget() {
    let exr = scratch("budget", "cap").join("c.exr");
    let line = render("--time-budget 60s --spp 2 --exr", &exr);
    assert!(line.contains("2 spp reached (the --spp cap)"), "{line}");
}

/// The error target: the estimate printed is at or below the target, and
/// the image is the same bytes on one thread and on three.
#[test]
fn a_target_error_is_reached_the_same_on_one_and_three_threads() {
    let dir = scratch("budget", "error");
    let run = |threads: &str| {
        let exr = dir.join(format!("e{threads}.exr"));
        let line = render(&format!("--target-error 0.2 --threads {threads} --exr"), &exr);
        (line, std::fs::read(&exr).unwrap())
    };
    let (line, one) = run("1");
    let estimate = number_after(&line, "estimated relative error ");
    assert!(estimate <= 0.2 && estimate > 0.05, "{line}");
    assert!(line.contains("(reached)"), "{line}");
    let (line3, three) = run("3");
    assert!(one == three, "the EXRs differ between 1 and 3 threads");
    assert_eq!(estimate, number_after(&line3, "estimated relative error "));
}

#[test]
fn bad_budgets_and_targets_are_clear_errors() {
    for (flag, value, says) in [
        ("--time-budget", "2", "give a unit, e.g. 2s, 1.5s or 500ms"),
        ("--time-budget", "1.5h", "give a unit"),
        ("--time-budget", "0ms", "from 1ms to 24 hours"),
        ("--time-budget", "fast s", "not a time such as 2s"),
        ("--target-error", "0", "between 0 and 1"),
        ("--target-error", "1.5", "between 0 and 1"),
    ] {
        let err = run_fail(2, "render res/scenes/seed.toml -o x.png", &[&format!("{flag}={value}")]);
        assert!(err.contains(says), "{flag} {value}: {err}");
    }
    let both = "render res/scenes/seed.toml -o x.png --time-budget 1s --target-error 0.1";
    let err = run_fail(2, both, &[]);
    assert!(err.contains("cannot be used with"), "{err}");
}
