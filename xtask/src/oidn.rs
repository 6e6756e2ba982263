//! `cargo xtask oidn`: installs Intel Open Image Denoise (OIDN) for
//! `lucent render --denoise` without a system package.
//!
//! The official OIDN 2.x Linux binaries ship inside the PyPI package
//! `pyoidn` (a wheel, i.e. a zip). This task downloads the pinned version
//! with `pip download --no-deps` (pip checks the file against the index's
//! hash) and unpacks only the CPU denoiser's libraries, with their licence,
//! into `target/oidn/lib`, where `lucent_denoise::Denoiser::load` looks
//! (their `$ORIGIN/../lib` run path finds each other there). Python 3 with
//! pip is the only tool needed; nothing is installed outside `target/`.

use std::path::Path;
use std::process::Command;

/// The pinned pyoidn release (OIDN 2.5.1).
pub const PYOIDN: &str = "pyoidn==2.5.1.0";

/// Members of the wheel unpacked into `target/oidn/lib`: the API library
/// (its soname), the core and CPU device it loads, TBB, and the licence.
const MEMBERS: [(&str, &str); 5] = [
    ("pyoidn/oidn/lib/libOpenImageDenoise.so.2", "libOpenImageDenoise.so.2"),
    (
        "pyoidn/oidn/lib/libOpenImageDenoise_core.so.2.5.1",
        "libOpenImageDenoise_core.so.2.5.1",
    ),
    (
        "pyoidn/oidn/lib/libOpenImageDenoise_device_cpu.so.2.5.1",
        "libOpenImageDenoise_device_cpu.so.2.5.1",
    ),
    ("pyoidn/oidn/lib/libtbb.so.12", "libtbb.so.12"),
    ("pyoidn-2.5.1.0.dist-info/licenses/LICENSE", "LICENSE-pyoidn.txt"),
];

/// Runs the task; `--force` reinstalls.
pub fn install(args: &[String]) -> Result<(), String> {
    let force = match args {
        [] => false,
        [f] if f == "--force" => true,
        _ => return Err("usage: cargo xtask oidn [--force]".to_owned()),
    };
    if !(cfg!(target_os = "linux") && cfg!(target_arch = "x86_64")) {
        return Err(format!(
            "the pyoidn wheel holds Linux x86-64 binaries; on this platform install OIDN 2 from \
             https://www.openimagedenoise.org and set {} to the library",
            "LUCENT_OIDN"
        ));
    }
    let dir = crate::root().join("target/oidn");
    let lib = dir.join("lib");
    if !force && MEMBERS.iter().all(|(_, name)| lib.join(name).is_file()) {
        println!("OIDN is installed in {} (--force reinstalls)", lib.display());
        return Ok(());
    }
    let python = ["python3", "python"]
        .into_iter()
        .find(|p| crate::has_program(p))
        .ok_or("cargo xtask oidn needs Python 3 with pip (to download the pyoidn wheel from PyPI)")?;
    let download = dir.join("download");
    let _ = std::fs::remove_dir_all(&download);
    std::fs::create_dir_all(&download).map_err(|e| format!("{}: {e}", download.display()))?;
    crate::run(
        Command::new(python)
            .args([
                "-m",
                "pip",
                "download",
                "--no-deps",
                "--only-binary=:all:",
                "--disable-pip-version-check",
            ])
            .args(["-d"])
            .arg(&download)
            .arg(PYOIDN),
    )
    .map_err(|e| format!("{e}; is pip installed (python3 -m pip --version)?"))?;
    let wheel = std::fs::read_dir(&download)
        .map_err(|e| format!("{}: {e}", download.display()))?
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .ok_or_else(|| format!("pip left no wheel in {}", download.display()))?;
    unpack(python, &wheel, &lib)?;
    let _ = std::fs::remove_dir_all(&download);
    println!(
        "installed OIDN ({PYOIDN}) in {}; `lucent render --denoise` finds it there",
        lib.display()
    );
    Ok(())
}

/// Unpacks [`MEMBERS`] of `wheel` into `lib` with Python's zipfile (std
/// Rust has no zip reader; Python is already needed for pip).
fn unpack(python: &str, wheel: &Path, lib: &Path) -> Result<(), String> {
    std::fs::create_dir_all(lib).map_err(|e| format!("{}: {e}", lib.display()))?;
    let pairs: Vec<String> = MEMBERS.iter().map(|(m, n)| format!("({m:?}, {n:?})")).collect();
    let script = format!(
        "import sys, zipfile, os, shutil\n\
         z = zipfile.ZipFile(sys.argv[1])\n\
         for member, name in [{}]:\n\
         \x20   out = os.path.join(sys.argv[2], name)\n\
         \x20   with z.open(member) as src, open(out + '.part', 'wb') as dst:\n\
         \x20       shutil.copyfileobj(src, dst)\n\
         \x20   os.replace(out + '.part', out)\n\
         \x20   print('  ' + out)\n",
        pairs.join(", ")
    );
    crate::run(Command::new(python).args(["-c", &script]).arg(wheel).arg(lib))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn members_land_under_their_own_names_in_one_lib_directory() {
        for (member, name) in MEMBERS {
            assert!(member.ends_with(name) || name.starts_with("LICENSE"), "{member}");
            assert!(!name.contains('/'), "{name}");
        }
        // The name lucent-denoise loads is among them.
        assert!(MEMBERS.iter().any(|(_, n)| *n == "libOpenImageDenoise.so.2"));
        assert!(install(&["--bogus".to_owned()]).is_err());
    }
}
