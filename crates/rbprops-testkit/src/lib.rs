//! Test support for the rbprops workspace (a dev-dependency of the other crates).
//!
//! One policy for tests that need a tool from outside Rust:
//! - the tool is looked for (Python: `$RBPROPS_PYTHON`, else `python3`, and the modules the
//!   test imports are probed; Chromium: `$RBPROPS_CHROMIUM`, else the usual install paths);
//! - when it is missing the test prints why on stderr and returns early (it passes);
//! - unless `RBPROPS_REQUIRE_PYTHON=1` / `RBPROPS_REQUIRE_CHROMIUM=1` is set (CI sets both),
//!   in which case a missing tool fails the test, so CI never passes by skipping.
#![warn(missing_docs)]

pub mod lcg;
pub mod synthetic;

pub use lcg::Lcg;

use rbprops_core::{
    rigid_body_modes, rigid_transform, Channel, Mat3, Mat6, Point, RigidBodyProperties, RigidMode,
    Vec3,
};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository's root directory (fixtures, scripts and specs are found from here).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("the testkit crate lives in crates/ of the repository")
}

/// numpy and pyuff: what the reference generator (`scripts/refgen`) and the H1 export
/// script need.
pub const NUMPY_PYUFF: &[&str] = &["numpy", "pyuff"];

/// A command that runs the reference generator `scripts/refgen/rbref.py` with `py`
/// (from [`python`] with [`NUMPY_PYUFF`]); the caller adds the case and options.
pub fn refgen(py: &str) -> Command {
    let mut cmd = Command::new(py);
    cmd.arg(repo_root().join("scripts/refgen/rbref.py"));
    cmd
}

/// Whether `var` is set to `1` (the CI's "a missing tool is a failure").
fn required(var: &str) -> bool {
    std::env::var_os(var).is_some_and(|v| v == "1")
}

/// A Python interpreter that imports every module of `modules`, or `None` (after a note
/// on stderr) when there is none. Looks at `$RBPROPS_PYTHON`, else `python3`.
///
/// # Panics
/// When `RBPROPS_REQUIRE_PYTHON=1` and the interpreter is missing or lacks a module.
pub fn python(modules: &[&str]) -> Option<String> {
    let py = std::env::var("RBPROPS_PYTHON")
        .ok()
        .filter(|p| !p.is_empty())
        .unwrap_or_else(|| "python3".into());
    let import = format!("import {}", modules.join(", "));
    let found = Command::new(&py)
        .args(["-c", &import])
        .output()
        .is_ok_and(|o| o.status.success());
    if found {
        return Some(py);
    }
    let why =
        format!("`{py} -c '{import}'` failed (set RBPROPS_PYTHON to a Python with these modules)");
    assert!(
        !required("RBPROPS_REQUIRE_PYTHON"),
        "RBPROPS_REQUIRE_PYTHON=1 but {why}"
    );
    eprintln!("skipping: {why}; RBPROPS_REQUIRE_PYTHON=1 makes this a failure");
    None
}

/// A headless-capable Chromium, or `None` (after a note on stderr) when none is installed.
///
/// # Panics
/// When `RBPROPS_REQUIRE_CHROMIUM=1` and no Chromium is found.
pub fn chromium() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("RBPROPS_CHROMIUM").map(PathBuf::from),
        Some(PathBuf::from("/usr/bin/chromium")),
        Some(PathBuf::from("/usr/bin/chromium-browser")),
        Some(PathBuf::from("/usr/bin/google-chrome")),
    ];
    if let Some(p) = candidates.into_iter().flatten().find(|p| p.is_file()) {
        return Some(p);
    }
    let why = "no chromium found (apt-get install chromium, or set RBPROPS_CHROMIUM)";
    assert!(
        !required("RBPROPS_REQUIRE_CHROMIUM"),
        "RBPROPS_REQUIRE_CHROMIUM=1 but {why}"
    );
    eprintln!("skipping the browser check: {why}; RBPROPS_REQUIRE_CHROMIUM=1 makes this a failure");
    None
}

/// `out` when its process succeeded; otherwise a panic that shows its stdout and stderr.
#[track_caller]
pub fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "{}\n{}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A triaxial accelerometer at `p`: the point `id` and its channels `{id}x`, `{id}y`,
/// `{id}z` along the body axes.
pub fn triaxial(id: &str, p: Vec3) -> (Point, Vec<Channel>) {
    (
        Point {
            id: id.into(),
            position: p,
        },
        Channel::triaxial(id, p),
    )
}

/// The stiffness about the origin of point springs on a rigid body:
/// `K = Σ T(a)ᵀ diag(k) T(a)` over the springs `(a, k)`, each attached at `a` with
/// stiffness `k` along x, y and z.
pub fn spring_stiffness(springs: impl IntoIterator<Item = (Vec3, [f64; 3])>) -> Mat6 {
    springs.into_iter().fold(Mat6::zeros(), |acc, (a, k)| {
        let t = rigid_transform(&a);
        acc + t.transpose() * Mat3::from_diagonal(&Vec3::from(k)) * t
    })
}

/// The rigid-body modes of `body` on the suspension stiffness `k` (ascending frequency,
/// mass-normalised shapes), mode `r` (0-based) with damping ratio `zeta(r)`.
///
/// # Panics
/// When `k` gives no stable suspension.
pub fn rigid_modes(
    body: &RigidBodyProperties,
    k: &Mat6,
    zeta: impl Fn(usize) -> f64,
) -> Vec<RigidMode> {
    rigid_body_modes(&body.mass_matrix().0, k)
        .expect("the springs give a stable suspension")
        .into_iter()
        .enumerate()
        .map(|(r, (w, shape))| RigidMode {
            frequency_hz: w / (2.0 * std::f64::consts::PI),
            damping_ratio: zeta(r),
            shape,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repo_root_holds_the_workspace_manifest() {
        let toml = std::fs::read_to_string(repo_root().join("Cargo.toml")).unwrap();
        assert!(toml.contains("[workspace]"));
    }

    /// Without the requirement a missing module is a skip (`None`); with it (CI), a panic.
    #[test]
    fn a_missing_module_is_a_skip_or_a_failure_as_required() {
        let probe = std::panic::catch_unwind(|| python(&["rbprops_no_such_module_xyz"]));
        if required("RBPROPS_REQUIRE_PYTHON") {
            assert!(
                probe.is_err(),
                "a missing module passed under the requirement"
            );
        } else {
            assert_eq!(probe.ok(), Some(None));
        }
    }

    #[test]
    fn triaxial_channels_are_the_unit_axes() {
        let (pt, ch) = triaxial("A", Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(pt.id, "A");
        assert_eq!(ch.len(), 3);
        for (k, c) in ch.iter().enumerate() {
            assert_eq!(c.direction[k], 1.0);
            assert_eq!(c.direction.norm(), 1.0);
            assert_eq!(c.point, "A");
        }
        assert_eq!(ch[2].id, "Az");
    }
}
