//! A campaign file's `[frf_est]` table: the campaign makes its time-history exports into
//! FRFs exactly as `frf-est` does with the same options on its command line (recordings of
//! `fixtures/timehist`, from the independent generator), and refuses bad values naming the
//! file and key.

use crate::common::rbprops;
use rbprops_cli::campaign::CampaignConfig;
use rbprops_core::records::PROCESSING_TOPIC;
use rbprops_testkit::{ok, repo_root};
use std::path::Path;
use std::process::Command;

fn fixture(name: &str) -> std::path::PathBuf {
    repo_root().join("fixtures/timehist").join(name)
}

/// The run a campaign item reads from `uff` with the campaign file `toml` (as
/// `rbprops campaign` reads it: `CampaignConfig::resolve`, then the UFF reader).
fn campaign_read(dir: &Path, uff: &Path, toml: &str) -> rbprops_formats::RunRecord {
    let file = dir.join("campaign.toml");
    std::fs::write(&file, toml).unwrap();
    let opts = CampaignConfig::read(&file)
        .unwrap()
        .resolve(dir, "campaign.toml", None)
        .unwrap();
    let uff_opts = rbprops_cli::UffInputOptions {
        estimation: opts.estimation,
        ..Default::default()
    };
    rbprops_cli::read_stage_input_quiet("read", Some(uff), &Default::default(), &uff_opts)
        .unwrap()
        .record
}

/// `frf-est uff ARGS -o out.mcap`, read back.
fn frf_est(dir: &Path, uff: &Path, args: &[&str]) -> rbprops_formats::RunRecord {
    let out = dir.join("frf-est.mcap");
    ok(Command::new(env!("CARGO_BIN_EXE_frf-est"))
        .arg(uff)
        .args(args)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap());
    rbprops_cli::read_input(Some(&out)).unwrap().record
}

fn processing(rec: &rbprops_formats::RunRecord) -> serde_json::Value {
    rec.get_one::<serde_json::Value>(PROCESSING_TOPIC)
        .unwrap()
        .expect("a processing topic")
}

/// The FRFs (every value, bit for bit) and the processing record (windows, hits,
/// averages) of two runs are the same.
fn assert_same_estimate(
    a: &rbprops_formats::RunRecord,
    b: &rbprops_formats::RunRecord,
    what: &str,
) {
    let (fa, fb) = (a.frf.as_ref().unwrap(), b.frf.as_ref().unwrap());
    assert_eq!(fa.frequency_hz, fb.frequency_hz, "{what}: axis");
    assert!(fa == fb, "{what}: FRFs differ");
    assert_eq!(processing(a), processing(b), "{what}: processing");
}

#[test]
fn frf_est_table_gives_what_frf_est_gives_with_those_options() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let cases: [(&str, &str, &[&str]); 2] = [
        // Per-hit records: H2, the generator's windows (τ = 0.5 s; force window from the
        // 0.125 s pretrigger to 20 ms after the pulse), a band, ADC ranges, the force DOF.
        (
            "small-per-hit.uff",
            "[frf_est]\nestimator = \"h2\"\nwindow = 0.5\nforce_window = [0.125, 0.02]\ntaper_s = 0.005\nband_hz = [1.0, 12.0]\nforce_range = 400.0\nresponse_range = 200.0\nmin_hits = 2\n",
            &[
                "--estimator", "h2", "--window", "0.5", "--force-window", "0.125:0.02", "--taper", "0.005",
                "--band", "1:12", "--force-range", "400", "--response-range", "200", "--min-hits", "2",
            ],
        ),
        // Continuous throughput records: trigger, pretrigger and record length given, no
        // force window, the exponential window on the response only, rejected hits kept.
        (
            "small-throughput-58b.uff",
            "[frf_est]\nestimator = \"hv\"\nwindow = \"none\"\nwindow_response_only = true\nforce_window = \"none\"\ntrigger = 0.2\npretrigger_s = 0.125\nrecord_s = 2.0\nkeep_rejected = true\nmin_hits = 3\n",
            &[
                "--estimator", "hv", "--window", "none", "--window-response-only", "--force-window", "none",
                "--trigger", "0.2", "--pretrigger", "0.125", "--record-s", "2", "--keep-rejected", "--min-hits", "3",
            ],
        ),
    ];
    for (file, toml, args) in cases {
        let uff = fixture(file);
        let from_campaign = campaign_read(d, &uff, toml);
        let from_frf_est = frf_est(d, &uff, args);
        assert_same_estimate(&from_campaign, &from_frf_est, file);
        // The options matter: frf-est's defaults give another estimate.
        let defaults = campaign_read(d, &uff, "");
        assert!(
            defaults.frf != from_campaign.frf
                || processing(&defaults) != processing(&from_campaign),
            "{file}: the [frf_est] options changed nothing"
        );
        assert_same_estimate(
            &defaults,
            &frf_est(d, &uff, &[]),
            &format!("{file}, defaults"),
        );
    }
}

#[test]
fn campaign_applies_its_frf_est_table_and_refuses_bad_values() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("campaign");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(fixture("small-per-hit.uff"), dir.join("small-per-hit.uff")).unwrap();
    let run = |toml: &str| -> (bool, String, String) {
        std::fs::write(dir.join("campaign.toml"), toml).unwrap();
        let out = rbprops()
            .arg("campaign")
            .arg(&dir)
            .args(["--uncertainty", "linearised"])
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // One triaxial accelerometer cannot give the rigid-body properties: the item fails
    // after its FRFs were estimated. Asking for three accepted hits stops it earlier, at
    // the estimate (each excitation has one rejected hit of three: a double hit, a clip);
    // with the rejected hits kept, three are averaged and it fails at the geometry again.
    let (_, table, _) = run("");
    assert!(
        table.contains("cannot resolve all six rigid-body motions"),
        "{table}"
    );
    let (good, table, _) = run("[frf_est]\nmin_hits = 3\n");
    assert!(!good);
    assert!(table.contains("2 of 3 hits accepted, 3 needed"), "{table}");
    let (_, table, _) = run("[frf_est]\nmin_hits = 3\nkeep_rejected = true\n");
    assert!(
        table.contains("cannot resolve all six rigid-body motions"),
        "{table}"
    );

    for (toml, expect) in [
        ("[frf_est]\nmin_hits = 1\n", "[frf_est] min_hits = 1"),
        (
            "[frf_est]\nwindow = \"exp\"\n",
            "[frf_est] window = \"exp\"",
        ),
        ("[frf_est]\nwindow = -2.0\n", "[frf_est] window = -2"),
        (
            "[frf_est]\nestimator = \"h3\"\n",
            "[frf_est] estimator = \"h3\"",
        ),
        ("[frf_est]\ntrigger = 1.5\n", "[frf_est] trigger = 1.5"),
        (
            "[frf_est]\nband_hz = [5.0, 1.0]\n",
            "[frf_est] band_hz = [5, 1]",
        ),
        (
            "[frf_est]\nforce_window = [-0.1, 0.05]\n",
            "[frf_est] force_window",
        ),
        (
            "[frf_est]\nforce_window = \"none\"\ntaper_s = 0.01\n",
            "no force window to taper",
        ),
        (
            "[frf_est]\nforce_dof = [\"201\"]\n",
            "[frf_est] force_dof = \"201\"",
        ),
        ("[frf_est]\nrecord = 2.0\n", "unknown field `record`"),
    ] {
        let (good, table, err) = run(toml);
        assert!(!good && table.is_empty(), "{toml}: {table}");
        assert!(
            err.contains("campaign.toml") && err.contains(expect),
            "{toml}: {err}"
        );
    }
}
