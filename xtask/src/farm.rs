//! `cargo xtask farm`: a split render and a turntable on a real Slurm
//! cluster of one node, brought up here and torn down again.
//!
//! It starts `munged` (with a fresh key), `slurmctld` and `slurmd` from
//! Debian's `munge` and `slurm-wlm` packages, each in the foreground as a
//! child of this process, with every file (configuration, state, logs,
//! sockets, outputs) under `target/farm/` and ports of their own, so it
//! touches nothing of a Slurm or munge the machine may run. Then it submits
//! the shipped job scripts of `res/farm/`: `submit-split.sh` (an array job
//! of `--part K/N` renders and a merge job that depends on it) and
//! `turntable.sbatch` (an array over frame ranges); waits for them; renders
//! the same images in one process; and compares the files with `cmp`.
//! Whatever happens, it stops the daemons it started (SIGTERM, then
//! SIGKILL) before it returns.
//!
//! It needs root (slurmd runs jobs as their user and the daemons run as
//! root here) and the packages: `apt-get install slurm-wlm munge`.

use crate::{cargo, has_program, root};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The scene every render here uses: small, so a debug build is quick.
const SCENE: &str = "res/scenes/cornell-mitsuba.toml";
/// The split render: shares, and the flags of every render.
const PARTS: u32 = 3;
const SPLIT_FLAGS: &[&str] = &[
    "--size",
    "64x48",
    "--spp",
    "12",
    "--integrator",
    "path",
    "--max-depth",
    "8",
];
/// The turntable: frames, frames per array task, flags.
const FRAMES: u32 = 6;
const CHUNK: u32 = 2;
const TURNTABLE_FLAGS: &[&str] = &["--size", "48x36", "--spp", "2"];
/// Ports of this cluster's daemons (not Slurm's defaults, 6817 and 6818).
const CTLD_PORT: u16 = 16817;
const SLURMD_PORT: u16 = 16818;

/// The daemons started, stopped in reverse order when dropped.
struct Daemons {
    children: Vec<(&'static str, Child)>,
}

impl Drop for Daemons {
    fn drop(&mut self) {
        while let Some((name, mut child)) = self.children.pop() {
            let pid = child.id().to_string();
            let _ = Command::new("kill").args(["-TERM", &pid]).status();
            let deadline = Instant::now() + Duration::from_secs(10);
            let stopped = loop {
                match child.try_wait() {
                    Ok(Some(_)) => break true,
                    Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(100)),
                    _ => break false,
                }
            };
            if !stopped {
                let _ = child.kill();
                let _ = child.wait();
            }
            println!(
                "farm: stopped {name} (pid {pid}{})",
                if stopped { "" } else { ", killed" }
            );
        }
    }
}

impl Daemons {
    fn start(&mut self, name: &'static str, cmd: &mut Command, log: &Path) -> Result<(), String> {
        let out = std::fs::File::create(log).map_err(|e| format!("{}: {e}", log.display()))?;
        let err = out.try_clone().map_err(|e| e.to_string())?;
        let child = cmd
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .map_err(|e| format!("cannot start {name}: {e}"))?;
        println!("farm: started {name} (pid {})", child.id());
        self.children.push((name, child));
        Ok(())
    }

    /// Fails if a daemon has already exited.
    fn check_alive(&mut self, dir: &Path) -> Result<(), String> {
        for (name, child) in &mut self.children {
            if let Ok(Some(status)) = child.try_wait() {
                return Err(format!(
                    "{name} exited ({status}); see {}/{name}.out and its log",
                    dir.display()
                ));
            }
        }
        Ok(())
    }
}

fn usage() -> String {
    "usage: cargo xtask farm [--release] [--no-build]".to_owned()
}

/// Runs the farm check; see the module documentation.
pub fn farm(args: &[String]) -> Result<(), String> {
    let (mut release, mut build) = (false, true);
    for a in args {
        match a.as_str() {
            "--release" => release = true,
            "--no-build" => build = false,
            _ => return Err(usage()),
        }
    }
    for p in [
        "munged",
        "munge",
        "slurmctld",
        "slurmd",
        "sbatch",
        "squeue",
        "sinfo",
        "scontrol",
        "cmp",
    ] {
        if !has_program(p) {
            return Err(format!(
                "`{p}` is not installed: cargo xtask farm needs Debian's slurm-wlm and munge packages \
(apt-get install slurm-wlm munge)"
            ));
        }
    }
    let uid = Command::new("id").arg("-u").output().map_err(|e| e.to_string())?;
    if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
        return Err("cargo xtask farm runs Slurm's daemons and must run as root".to_owned());
    }
    let start = Instant::now();
    let root = root();
    if build {
        let mut cmd = cargo();
        cmd.args(["build", "-p", "lucent"]);
        if release {
            cmd.arg("--release");
        }
        crate::run(&mut cmd)?;
    }
    let lucent = root
        .join("target")
        .join(if release { "release" } else { "debug" })
        .join("lucent");
    if !lucent.exists() {
        return Err(format!("{} is missing: build it (drop --no-build)", lucent.display()));
    }
    let dir = root.join("target/farm");
    let _ = std::fs::remove_dir_all(&dir);
    for d in ["munge", "state", "spool", "jobs", "single"] {
        std::fs::create_dir_all(dir.join(d)).map_err(|e| format!("{}: {e}", dir.join(d).display()))?;
    }
    let conf = write_config(&dir)?;
    let mut daemons = Daemons { children: Vec::new() };
    let result = bring_up_and_check(&mut daemons, &dir, &conf, &lucent, &root);
    if result.is_err() {
        // Cancel what may still run before the daemons go.
        let _ = slurm(&conf, "scancel", &["--user=root"]);
    }
    drop(daemons);
    result?;
    println!(
        "farm: passed in {:.1} s: the merged split render and the turntable's frames equal the single-process renders byte for byte",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// A munge key and slurm.conf under `dir`; returns the configuration's path.
fn write_config(dir: &Path) -> Result<PathBuf, String> {
    let io = |p: &Path| {
        let p = p.display().to_string();
        move |e: std::io::Error| format!("{p}: {e}")
    };
    let key = dir.join("munge/munge.key");
    let random = Command::new("head")
        .args(["-c", "1024", "/dev/urandom"])
        .output()
        .map_err(|e| e.to_string())?;
    std::fs::write(&key, &random.stdout).map_err(io(&key))?;
    run_quiet(Command::new("chmod").args(["600"]).arg(&key))?;
    run_quiet(Command::new("chmod").args(["755"]).arg(dir.join("munge")))?;
    // The node as slurmd sees it (CPUs, sockets, memory), so it is not
    // drained for disagreeing with the configuration; both daemons are
    // reached on 127.0.0.1, whether or not the host name resolves.
    let node = Command::new("slurmd").arg("-C").output().map_err(|e| e.to_string())?;
    let node_line = String::from_utf8_lossy(&node.stdout)
        .lines()
        .find(|l| l.starts_with("NodeName="))
        .map(str::to_owned)
        .ok_or("slurmd -C printed no NodeName line")?;
    let host = node_line
        .split_whitespace()
        .next()
        .and_then(|f| f.strip_prefix("NodeName="))
        .unwrap_or("localhost")
        .to_owned();
    let d = dir.display();
    let text = format!(
        "# Written by cargo xtask farm: a one-node cluster for one check.
ClusterName=lucentfarm
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={CTLD_PORT}
SlurmdPort={SLURMD_PORT}
AuthType=auth/munge
AuthInfo=socket={d}/munge/munge.sock
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/slurmctld.log
SlurmdLogFile={d}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MinJobAge=600
{node_line} NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=farm Nodes={host} Default=YES MaxTime=INFINITE State=UP
"
    );
    let conf = dir.join("slurm.conf");
    std::fs::write(&conf, text).map_err(io(&conf))?;
    Ok(conf)
}

fn bring_up_and_check(
    daemons: &mut Daemons,
    dir: &Path,
    conf: &Path,
    lucent: &Path,
    root: &Path,
) -> Result<(), String> {
    let m = dir.join("munge");
    let arg = |k: &str, p: PathBuf| format!("--{k}={}", p.display());
    daemons.start(
        "munged",
        Command::new("munged").args([
            "--foreground".to_owned(),
            "--force".to_owned(),
            arg("socket", m.join("munge.sock")),
            arg("key-file", m.join("munge.key")),
            arg("log-file", m.join("munged.log")),
            arg("pid-file", m.join("munged.pid")),
            arg("seed-file", m.join("munged.seed")),
        ]),
        &dir.join("munged.out"),
    )?;
    wait_for("munge's socket", Duration::from_secs(20), || {
        Ok(m.join("munge.sock").exists())
    })?;
    daemons.start(
        "slurmctld",
        Command::new("slurmctld").arg("-D").arg("-i").arg("-f").arg(conf),
        &dir.join("slurmctld.out"),
    )?;
    daemons.start(
        "slurmd",
        Command::new("slurmd").arg("-D").arg("-f").arg(conf),
        &dir.join("slurmd.out"),
    )?;
    let t = Instant::now();
    wait_for("the node to be idle", Duration::from_secs(60), || {
        daemons.check_alive(dir)?;
        Ok(slurm(conf, "sinfo", &["-h", "-o", "%T"]).is_ok_and(|s| s.trim() == "idle"))
    })?;
    println!(
        "farm: one-node cluster up in {:.1} s ({})",
        t.elapsed().as_secs_f64(),
        slurm(conf, "sinfo", &["-h", "-o", "partition %P, node %N, %c CPUs, %T"])?.trim()
    );

    let scene = root.join(SCENE);
    let scene = scene.to_str().ok_or("the repository path is not UTF-8")?;
    let jobs = dir.join("jobs");
    let jobs_s = jobs.to_str().ok_or("not UTF-8")?;
    let farm_dir = root.join("res/farm");
    let t = Instant::now();
    let split_out = format!("{jobs_s}/split");
    let parts = PARTS.to_string();
    let mut submit_args = vec![parts.as_str(), scene, split_out.as_str()];
    submit_args.extend_from_slice(SPLIT_FLAGS);
    let ids = submit(
        Command::new(farm_dir.join("submit-split.sh")).args(&submit_args),
        conf,
        lucent,
        &jobs,
    )?;
    let ids: Vec<String> = ids.split_whitespace().map(str::to_owned).collect();
    println!(
        "farm: submitted the split render: array job {} ({PARTS} tasks of `lucent render --part K/{PARTS}`), merge job {} (afterok)",
        ids.first().map_or("?", |s| s.as_str()),
        ids.get(1).map_or("?", |s| s.as_str())
    );
    let tasks = FRAMES.div_ceil(CHUNK);
    let frames_out = format!("{jobs_s}/turntable");
    let (frames, chunk, array) = (
        FRAMES.to_string(),
        CHUNK.to_string(),
        format!("--array=0-{}", tasks - 1),
    );
    let script = farm_dir.join("turntable.sbatch");
    let mut tt_args = vec!["--parsable", array.as_str(), script.to_str().ok_or("not UTF-8")?, scene];
    tt_args.extend_from_slice(&[frames_out.as_str(), frames.as_str(), chunk.as_str()]);
    tt_args.extend_from_slice(TURNTABLE_FLAGS);
    let tt = submit(Command::new("sbatch").args(&tt_args), conf, lucent, &jobs)?;
    println!(
        "farm: submitted the turntable: array job {} ({tasks} tasks of {CHUNK} frames)",
        tt.trim()
    );
    let mut all: Vec<String> = ids.clone();
    all.push(tt.trim().to_owned());
    wait_for("the jobs to finish", Duration::from_secs(600), || {
        daemons.check_alive(dir)?;
        Ok(slurm(conf, "squeue", &["-h", "-o", "%i"])?.trim().is_empty())
    })?;
    for id in &all {
        let show = slurm(conf, "scontrol", &["show", "job", id])?;
        let states: Vec<&str> = show
            .split_whitespace()
            .filter_map(|f| f.strip_prefix("JobState="))
            .collect();
        if states.is_empty() || states.iter().any(|s| *s != "COMPLETED") {
            return Err(format!(
                "job {id} ended {states:?}; its output is in {}",
                jobs.display()
            ));
        }
    }
    println!(
        "farm: all jobs COMPLETED in {:.1} s (submission to the last one)",
        t.elapsed().as_secs_f64()
    );

    // The same images in one process.
    let single = dir.join("single");
    let (png, exr) = (single.join("final.png"), single.join("final.exr"));
    let mut cmd = Command::new(lucent);
    cmd.arg("render")
        .arg(scene)
        .arg("-o")
        .arg(&png)
        .arg("--exr")
        .arg(&exr)
        .args(SPLIT_FLAGS);
    run_quiet(&mut cmd)?;
    let frames_single = single.join("turntable");
    std::fs::create_dir_all(&frames_single).map_err(|e| e.to_string())?;
    let mut cmd = Command::new(lucent);
    cmd.arg("render")
        .arg(scene)
        .arg("--turntable")
        .arg(&frames)
        .arg("-o")
        .arg(frames_single.join("f####.png"))
        .args(TURNTABLE_FLAGS);
    run_quiet(&mut cmd)?;
    let mut pairs = vec![(jobs.join("split/final.png"), png), (jobs.join("split/final.exr"), exr)];
    for f in 0..FRAMES {
        let name = format!("f{f:04}.png");
        pairs.push((jobs.join("turntable").join(&name), frames_single.join(&name)));
    }
    for (farm, one) in &pairs {
        let out = Command::new("cmp")
            .arg(farm)
            .arg(one)
            .output()
            .map_err(|e| e.to_string())?;
        if !out.status.success() {
            return Err(format!(
                "cmp {} {}: {}{}",
                farm.display(),
                one.display(),
                String::from_utf8_lossy(&out.stdout).trim(),
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        println!(
            "farm: cmp {} {}: identical",
            farm.strip_prefix(root).unwrap_or(farm).display(),
            one.strip_prefix(root).unwrap_or(one).display()
        );
    }
    Ok(())
}

/// Runs a submission command (sbatch or the submit script) in `cwd` with
/// the cluster's configuration and `LUCENT` set; returns its stdout.
fn submit(cmd: &mut Command, conf: &Path, lucent: &Path, cwd: &Path) -> Result<String, String> {
    let out = cmd
        .current_dir(cwd)
        .env("SLURM_CONF", conf)
        .env("LUCENT", lucent)
        .output()
        .map_err(|e| format!("{cmd:?}: {e}"))?;
    if !out.status.success() {
        return Err(format!("{cmd:?}: {}", String::from_utf8_lossy(&out.stderr).trim()));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Runs a Slurm client command against this cluster; returns its stdout.
fn slurm(conf: &Path, program: &str, args: &[&str]) -> Result<String, String> {
    let out = Command::new(program)
        .args(args)
        .env("SLURM_CONF", conf)
        .output()
        .map_err(|e| format!("{program}: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "{program} {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn run_quiet(cmd: &mut Command) -> Result<(), String> {
    let out = cmd.output().map_err(|e| format!("{cmd:?}: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!("{cmd:?}: {}", String::from_utf8_lossy(&out.stderr).trim()))
    }
}

/// Polls `ready` every 200 ms until it says yes, fails, or `limit` passes.
fn wait_for(what: &str, limit: Duration, mut ready: impl FnMut() -> Result<bool, String>) -> Result<(), String> {
    let deadline = Instant::now() + limit;
    loop {
        if ready()? {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(format!("gave up waiting for {what} after {} s", limit.as_secs()));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}
