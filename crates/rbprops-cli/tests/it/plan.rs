//! `rbprops plan`: the planned spec is one frf-sim reads, --plot writes the three views,
//! --evaluate --format json gives every property's predicted standard deviation, bad
//! candidates stop with an error and
//! no output.

use crate::common::rbprops;

fn spec_with_noise(dir: &std::path::Path) -> std::path::PathBuf {
    let text = rbprops_sim::example("test-case-2")
        .unwrap()
        .replace("relative = 0.0", "relative = 0.01");
    let p = dir.join("tc2.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn candidates(dir: &std::path::Path) -> std::path::PathBuf {
    let mut csv = String::from("id,x_m,y_m,z_m,role,dx,dy,dz\n");
    let mut k = 0;
    for x in [0.0, 0.36] {
        for y in [-0.15, 0.22] {
            for z in [-0.19, 0.17] {
                csv += &format!("p{k},{x},{y},{z},both,0,0,1\n");
                csv += &format!("p{k},{x},{y},{z},hit,1,0,0\n");
                csv += &format!("p{k},{x},{y},{z},hit,0,1,0\n");
                k += 1;
            }
        }
    }
    let p = dir.join("cands.csv");
    std::fs::write(&p, csv).unwrap();
    p
}

#[test]
fn plan_writes_a_spec_frf_sim_reads_and_evaluate_reports_json() {
    let dir = tempfile::tempdir().unwrap();
    let spec = spec_with_noise(dir.path());
    let cands = candidates(dir.path());
    let out = dir.path().join("plan.toml");
    let r = rbprops()
        .args(["plan"])
        .arg(&spec)
        .arg("--candidates")
        .arg(&cands)
        .args(["--sensors", "3", "--hits", "3", "-o"])
        .arg(&out)
        .arg("--plot")
        .arg(dir.path().join("figs"))
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for view in ["xy", "xz", "yz"] {
        let svg = std::fs::read_to_string(dir.path().join(format!("figs/plan-layout-{view}.svg")))
            .unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("sensors (triaxial)"));
    }
    let table = String::from_utf8(r.stdout).unwrap();
    assert!(table.contains("worst relative std"), "{table}");
    let planned = std::fs::read_to_string(&out).unwrap();
    let parsed = rbprops_sim::CampaignSpec::from_toml_str(&planned).unwrap();
    assert_eq!((parsed.sensors.len(), parsed.excitations.len()), (3, 3));
    rbprops_sim::simulate(&parsed).unwrap();

    let r = rbprops()
        .args(["plan"])
        .arg(&spec)
        .args(["--evaluate", "--format", "json"])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let props = j["setups"][0]["properties"].as_array().unwrap();
    assert_eq!(props.len(), 10);
    assert!(props.iter().all(|p| p["std"].as_f64().unwrap() > 0.0));
    assert!(j["setups"][0]["weakest"].is_string());
    assert!(j["setups"][0]["limit"].is_null());
}

#[test]
fn bad_candidates_stop_with_an_error_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let spec = spec_with_noise(dir.path());
    let cands = dir.path().join("bad.csv");
    std::fs::write(
        &cands,
        "id,x_m,y_m,z_m,role,dx,dy,dz\np1,0.1,zero,0,both,0,0,1\n",
    )
    .unwrap();
    let out = dir.path().join("plan.toml");
    let r = rbprops()
        .args(["plan"])
        .arg(&spec)
        .arg("--candidates")
        .arg(&cands)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(1));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("error:") && err.contains("bad.csv") && err.contains("line 2"),
        "{err}"
    );
    assert!(!out.exists());
}
