//! Builds the Force Dimension SDK test double (`fdsdk-double/src/lib.rs`) as shared libraries in
//! `OUT_DIR`, for the omega backend's tests, and tells the crate where they are through the
//! compile-time variables `FDSDK_DOUBLE` and `FDSDK_DOUBLE_NO_WATCHDOG`.
//!
//! Why here and not as a cargo dependency: cargo cannot depend on a `cdylib`'s file on stable,
//! and calling cargo from a test would fight over the build lock. The double has no
//! dependencies, so one `rustc --crate-type cdylib` (with the `rustc` cargo uses) builds it in
//! about a second, on any machine that can build this crate. It is rebuilt only when its source
//! changes. When cross-compiling (host ≠ target) nothing is built: the tests that need it say so.

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

const SOURCE: &str = "fdsdk-double/src/lib.rs";

fn main() {
    println!("cargo:rerun-if-changed={SOURCE}");
    println!("cargo:rerun-if-changed=build.rs");
    let (Some(out), Some(rustc)) = (env::var_os("OUT_DIR"), env::var_os("RUSTC")) else {
        return;
    };
    if env::var("HOST").ok() != env::var("TARGET").ok() {
        println!(
            "cargo:warning=cross-compiling: the SDK double is not built; omega tests will be skipped"
        );
        return;
    }
    let out = PathBuf::from(out);
    let variants = [
        ("FDSDK_DOUBLE", "dhd_double", None),
        (
            "FDSDK_DOUBLE_NO_WATCHDOG",
            "dhd_double_no_watchdog",
            Some("fdsdk_double_omit_watchdog"),
        ),
    ];
    for (var, name, cfg) in variants {
        match build(Path::new(&rustc), &out, name, cfg) {
            Ok(path) => println!("cargo:rustc-env={var}={}", path.display()),
            Err(e) => println!("cargo:warning=SDK double {name} not built: {e}"),
        }
    }
}

fn build(rustc: &Path, out: &Path, name: &str, cfg: Option<&str>) -> Result<PathBuf, String> {
    let file = out.join(format!(
        "{}{name}{}",
        env::consts::DLL_PREFIX,
        env::consts::DLL_SUFFIX
    ));
    let mut cmd = Command::new(rustc);
    cmd.args(["--edition=2024", "--crate-type=cdylib", "-Cdebuginfo=0"])
        .arg(format!("--crate-name={name}"))
        .arg("-o")
        .arg(&file)
        .arg(SOURCE);
    if let Some(cfg) = cfg {
        cmd.args(["--cfg", cfg]);
    }
    let output = cmd.output().map_err(|e| format!("cannot run rustc: {e}"))?;
    if output.status.success() {
        Ok(file)
    } else {
        Err(String::from_utf8_lossy(&output.stderr).into_owned())
    }
}
