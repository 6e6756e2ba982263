//! `cargo xtask fuzz`: builds the coverage-guided fuzz targets in `fuzz/`
//! (cargo-fuzz with libFuzzer, no sanitizer, so it runs on the stable
//! toolchain), seeds their corpora and runs them one at a time under
//! `nice`, with a memory ceiling, until each has done `--runs` executions
//! or spent `--time` seconds. A crash does not end a target's run: its
//! input is kept under `fuzz/artifacts/TARGET/` and fuzzing resumes from
//! the corpus, so one long unattended run finds more than one bug. Each
//! target's figures (executions, exec/s, coverage, crashes) are printed as
//! one line and appended to `fuzz/logs/summary.tsv`; libFuzzer's own output
//! is in `fuzz/logs/TARGET-N.log`. Never part of CI (see
//! docs/robustness.md, "Hostile input and fuzzing").

use crate::{cargo, has_program, root, run};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The fuzz targets, in the order they run, and the file extensions of the
/// `../shared/assets` files that seed them.
const TARGETS: &[(&str, &[&str])] = &[
    ("obj", &["obj"]),
    ("ply", &["ply"]),
    ("mtl", &["mtl"]),
    ("scene", &[]),
    ("texture", &[]),
    ("gltf", &["gltf", "glb"]),
    ("envmap", &["hdr"]),
];

/// Seeds bigger than this are cut (at a line end for text formats), so
/// executions stay fast; libFuzzer grows inputs from there.
const SEED_BYTES: usize = 4096;

/// At most this many crashes are collected per target before giving up on
/// it (a crash that recurs at once would otherwise spin).
const MAX_CRASHES: usize = 20;

struct Opts {
    targets: Vec<String>,
    runs: u64,
    seconds: u64,
    max_len: u32,
    rss_mb: u32,
    address_space_mb: u32,
    build: bool,
}

/// What one target's session did, summed over its restarts.
#[derive(Default)]
struct Tally {
    executions: u64,
    seconds: f64,
    coverage: String,
    crashes: Vec<String>,
    logs: Vec<PathBuf>,
}

pub fn fuzz(args: &[String]) -> Result<(), String> {
    let opts = parse(args)?;
    let dir = root().join("fuzz");
    if !has_program("cargo-fuzz") {
        return Err("cargo-fuzz is not installed: `cargo install cargo-fuzz --locked`".to_owned());
    }
    if opts.build {
        // `-s none`: no sanitizer, which needs no nightly; `-O -a`: optimised
        // with debug assertions and overflow checks.
        run(cargo().args(["fuzz", "build", "-s", "none", "-O", "-a"]))?;
    }
    for dir_name in ["logs", "artifacts", "corpus"] {
        std::fs::create_dir_all(dir.join(dir_name)).map_err(|e| format!("cannot create fuzz/{dir_name}: {e}"))?;
    }
    for target in &opts.targets {
        let corpus = seed_corpus(&dir, target)?;
        let tally = fuzz_target(&dir, target, &corpus, &opts)?;
        report(&dir, target, &tally)?;
    }
    Ok(())
}

fn parse(args: &[String]) -> Result<Opts, String> {
    let mut opts = Opts {
        targets: Vec::new(),
        runs: 10_000_000,
        seconds: 3600,
        max_len: 4096,
        rss_mb: 2048,
        address_space_mb: 0,
        build: true,
    };
    let mut it = args.iter();
    while let Some(arg) = it.next() {
        let mut number = |name: &str| -> Result<u64, String> {
            it.next()
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| format!("{name} needs a whole number"))
        };
        match arg.as_str() {
            "--runs" => opts.runs = number("--runs")?,
            "--time" => opts.seconds = number("--time")?,
            "--max-len" => opts.max_len = u32::try_from(number("--max-len")?).map_err(|e| e.to_string())?,
            "--rss-mb" => opts.rss_mb = u32::try_from(number("--rss-mb")?).map_err(|e| e.to_string())?,
            "--no-build" => opts.build = false,
            t if TARGETS.iter().any(|(name, _)| *name == t) => opts.targets.push(t.to_owned()),
            other => {
                let names: Vec<&str> = TARGETS.iter().map(|(n, _)| *n).collect();
                return Err(format!(
                    "fuzz: unknown argument '{other}' (targets: {})",
                    names.join(", ")
                ));
            }
        }
    }
    if opts.targets.is_empty() {
        opts.targets = TARGETS.iter().map(|(n, _)| (*n).to_owned()).collect();
    }
    // The address-space ceiling sits above libFuzzer's RSS limit so that
    // libFuzzer reports most memory blow-ups itself, and a huge allocation
    // that is never touched still fails.
    opts.address_space_mb = opts.rss_mb + 1024;
    Ok(opts)
}

/// Fills `fuzz/corpus/TARGET` from `fuzz/seeds/TARGET` and the shared
/// assets the first time; later runs reuse (and grow) what is there.
fn seed_corpus(dir: &Path, target: &str) -> Result<PathBuf, String> {
    let corpus = dir.join("corpus").join(target);
    let has_files = std::fs::read_dir(&corpus).is_ok_and(|mut d| d.next().is_some());
    if has_files {
        return Ok(corpus);
    }
    std::fs::create_dir_all(&corpus).map_err(|e| format!("cannot create {}: {e}", corpus.display()))?;
    let mut seeds = Vec::new();
    list_files(&dir.join("seeds").join(target), &[], &mut seeds);
    let exts = TARGETS.iter().find(|(n, _)| *n == target).map_or(&[][..], |(_, e)| e);
    let assets = root().join("../shared/assets");
    if exts.is_empty() {
        // Nothing in the shared assets for this target.
    } else if assets.is_dir() {
        list_files(&assets, exts, &mut seeds);
    } else {
        println!(
            "note: {} is absent: seeding {target} from fuzz/seeds only",
            assets.display()
        );
    }
    for seed in &seeds {
        let bytes = std::fs::read(seed).map_err(|e| format!("cannot read {}: {e}", seed.display()))?;
        // glTF seeds stay whole: a JSON document cut short does not parse.
        let bytes = if target == "gltf" {
            &bytes[..]
        } else {
            cut(&bytes, target != "texture")
        };
        // Name by path so same-named files of different folders both stay.
        let rel = seed
            .strip_prefix(&assets)
            .or_else(|_| seed.strip_prefix(dir))
            .unwrap_or(seed);
        let name = rel.to_string_lossy().replace(['/', '\\'], "-");
        std::fs::write(corpus.join(name), bytes).map_err(|e| format!("cannot write a seed: {e}"))?;
    }
    println!("{target}: seeded {} files into {}", seeds.len(), corpus.display());
    Ok(corpus)
}

/// The first `SEED_BYTES` of `bytes`, ending at a line end when `text`.
fn cut(bytes: &[u8], text: bool) -> &[u8] {
    if bytes.len() <= SEED_BYTES {
        return bytes;
    }
    let head = &bytes[..SEED_BYTES];
    match head.iter().rposition(|&b| b == b'\n') {
        Some(end) if text => &head[..=end],
        _ => head,
    }
}

/// Files under `dir` (recursively) whose extension is one of `exts` (any
/// file when `exts` is empty), sorted.
fn list_files(dir: &Path, exts: &[&str], out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            list_files(&p, exts, out);
        } else {
            let ext = p
                .extension()
                .and_then(|e| e.to_str())
                .unwrap_or_default()
                .to_ascii_lowercase();
            if exts.is_empty() || exts.contains(&ext.as_str()) {
                out.push(p);
            }
        }
    }
}

/// Runs one target until it has done `opts.runs` executions or spent
/// `opts.seconds`, restarting after each crash.
fn fuzz_target(dir: &Path, target: &str, corpus: &Path, opts: &Opts) -> Result<Tally, String> {
    let binary = dir.join("target/x86_64-unknown-linux-gnu/release").join(target);
    if !binary.is_file() {
        return Err(format!("{} is not built (drop --no-build)", binary.display()));
    }
    let artifacts = dir.join("artifacts").join(target);
    std::fs::create_dir_all(&artifacts).map_err(|e| format!("cannot create {}: {e}", artifacts.display()))?;
    let mut tally = Tally::default();
    let start = Instant::now();
    // Number logs after those of earlier invocations, so none is overwritten.
    let mut session = (1..)
        .find(|n| !dir.join("logs").join(format!("{target}-{n}.log")).exists())
        .unwrap_or(1)
        - 1;
    loop {
        let elapsed = start.elapsed().as_secs();
        if tally.executions >= opts.runs || elapsed >= opts.seconds || tally.crashes.len() >= MAX_CRASHES {
            break;
        }
        session += 1;
        let log = dir.join("logs").join(format!("{target}-{session}.log"));
        let before = artifact_names(&artifacts);
        let mut lib_fuzzer = vec![
            corpus.display().to_string(),
            format!("-runs={}", opts.runs - tally.executions),
            format!("-max_total_time={}", opts.seconds - elapsed),
            format!("-max_len={}", opts.max_len),
            format!("-rss_limit_mb={}", opts.rss_mb),
            "-timeout=10".to_owned(),
            "-print_final_stats=1".to_owned(),
            format!("-artifact_prefix={}/", artifacts.display()),
        ];
        let dict = dir.join("dicts").join(format!("{target}.dict"));
        if dict.is_file() {
            lib_fuzzer.push(format!("-dict={}", dict.display()));
        }
        let log_file = std::fs::File::create(&log).map_err(|e| format!("cannot create {}: {e}", log.display()))?;
        let err_file = log_file.try_clone().map_err(|e| e.to_string())?;
        // One fuzzer at a time, niced: the machine is shared.
        let script = format!(
            "ulimit -v {}; exec nice -n 15 \"$0\" \"$@\"",
            u64::from(opts.address_space_mb) * 1024
        );
        let mut cmd = Command::new("sh");
        cmd.arg("-c")
            .arg(script)
            .arg(&binary)
            .args(&lib_fuzzer)
            .current_dir(dir)
            .stdout(log_file)
            .stderr(err_file);
        println!("$ {} {} > {}", binary.display(), lib_fuzzer.join(" "), log.display());
        let status = cmd
            .status()
            .map_err(|e| format!("cannot run {}: {e}", binary.display()))?;
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let (executions, seconds) = executions_and_time(&text);
        tally.executions += executions;
        tally.seconds += seconds;
        if let Some(cov) = last_coverage(&text) {
            tally.coverage = cov;
        }
        tally.logs.push(log.clone());
        let new: Vec<String> = artifact_names(&artifacts)
            .into_iter()
            .filter(|a| !before.contains(a))
            .collect();
        if status.success() {
            break;
        }
        if new.is_empty() {
            return Err(format!(
                "{target}: libFuzzer failed ({status}) without an artifact; see {}",
                log.display()
            ));
        }
        println!("{target}: {status}: {} (see {})", new.join(", "), log.display());
        tally.crashes.extend(new);
    }
    Ok(tally)
}

fn artifact_names(dir: &Path) -> Vec<String> {
    let mut files = Vec::new();
    list_files(dir, &[], &mut files);
    files
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect()
}

/// Executions and seconds from libFuzzer's final statistics, or from its
/// last status line when it died without them.
fn executions_and_time(log: &str) -> (u64, f64) {
    let stat = |key: &str| {
        log.lines()
            .rev()
            .find_map(|l| l.strip_prefix(key).map(|v| v.trim().parse::<f64>().unwrap_or(0.0)))
    };
    let executions = stat("stat::number_of_executed_units:").map(|v| v as u64).or_else(|| {
        log.lines()
            .rev()
            .find_map(|l| l.strip_prefix('#')?.split_whitespace().next()?.parse().ok())
    });
    let rate = stat("stat::average_exec_per_sec:").unwrap_or(0.0);
    let executions = executions.unwrap_or(0);
    let seconds = if rate > 0.0 { executions as f64 / rate } else { 0.0 };
    (executions, seconds)
}

/// The `cov: N ft: M corp: C/S` part of libFuzzer's last status line.
fn last_coverage(log: &str) -> Option<String> {
    let line = log.lines().rev().find(|l| l.starts_with('#') && l.contains(" cov: "))?;
    let from = line.find("cov: ")?;
    let to = line
        .find(" lim: ")
        .or_else(|| line.find(" exec/s: "))
        .unwrap_or(line.len());
    Some(line[from..to].to_owned())
}

fn report(dir: &Path, target: &str, t: &Tally) -> Result<(), String> {
    let rate = if t.seconds > 0.0 {
        t.executions as f64 / t.seconds
    } else {
        0.0
    };
    let crashes = if t.crashes.is_empty() {
        "none".to_owned()
    } else {
        t.crashes.join(" ")
    };
    println!(
        "{target}: {} executions in {:.0} s ({rate:.0} exec/s) over {} run(s); {}; crashes: {crashes}",
        t.executions,
        t.seconds,
        t.logs.len(),
        t.coverage
    );
    let summary = dir.join("logs/summary.tsv");
    let line = format!(
        "{target}\t{}\t{:.0}\t{rate:.0}\t{}\t{}\t{crashes}\n",
        t.executions,
        t.seconds,
        t.coverage,
        t.crashes.len()
    );
    let mut text = std::fs::read_to_string(&summary)
        .unwrap_or_else(|_| "target\texecutions\tseconds\texec_per_s\tcoverage\tcrashes\tartifacts\n".to_owned());
    text.push_str(&line);
    std::fs::write(&summary, text).map_err(|e| format!("cannot write {}: {e}", summary.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_libfuzzer_statistics() {
        let log = "#1000\tNEW    cov: 10 ft: 20 corp: 5/1Kb lim: 4 exec/s: 0 rss: 30Mb L: 3/3 MS: 1 X-\n\
                   #20000\tDONE   cov: 12 ft: 25 corp: 6/2Kb lim: 8 exec/s: 10000 rss: 31Mb\n\
                   Done 20000 runs in 2 second(s)\n\
                   stat::number_of_executed_units: 20000\n\
                   stat::average_exec_per_sec:     10000\n";
        assert_eq!(executions_and_time(log), (20000, 2.0));
        assert_eq!(last_coverage(log).as_deref(), Some("cov: 12 ft: 25 corp: 6/2Kb"));
        // Killed before its final statistics: the last status line counts.
        let cut = "#1000\tNEW    cov: 10 ft: 20 corp: 5/1Kb lim: 4 exec/s: 0 rss: 30Mb\n";
        assert_eq!(executions_and_time(cut), (1000, 0.0));
    }

    #[test]
    fn seeds_are_cut_at_a_line_end() {
        let mut text = b"v 0 0 0\n".repeat(1000);
        text.extend(b"end");
        let cut_text = cut(&text, true);
        assert!(cut_text.len() <= SEED_BYTES && cut_text.ends_with(b"\n"));
        assert_eq!(cut(&text, false).len(), SEED_BYTES);
        assert_eq!(cut(b"small", true), b"small");
    }
}
