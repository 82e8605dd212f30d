//! Times `simulate` for 1,000 excitations × 9 channels (3 triaxial) × 4,096 lines.

use criterion::{criterion_group, criterion_main, Criterion};
use rbprops_sim::spec::{ExcitationSpec, NoiseSpec};
use rbprops_sim::{example, simulate, CampaignSpec};

/// Test Case II's body, suspension and sensors with 1,000 excitations spread over the
/// article and 4,096 lines.
fn big_spec(noise: bool) -> CampaignSpec {
    let mut spec = CampaignSpec::from_toml_str(example("test-case-2").unwrap()).unwrap();
    spec.frequency.lines = 4096;
    spec.excitations = (0..1000)
        .map(|k| {
            let t = k as f64;
            let d = nalgebra::Vector3::new((0.7 * t).sin(), (1.3 * t).cos(), 0.5 + (0.3 * t).sin())
                .normalize();
            ExcitationSpec {
                id: format!("F{k}"),
                at_m: [
                    0.36 * (0.37 * t).sin().abs(),
                    0.2 * (0.11 * t).cos(),
                    0.15 * (0.23 * t).sin(),
                ],
                direction: [d.x, d.y, d.z],
                setup: "A".into(),
                point: None,
            }
        })
        .collect();
    spec.noise = if noise {
        NoiseSpec {
            relative: 0.01,
            floor: 1e-9,
        }
    } else {
        NoiseSpec::default()
    };
    spec.validate().unwrap();
    spec
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("simulate_1000x9x4096");
    g.sample_size(10);
    for noise in [false, true] {
        let spec = big_spec(noise);
        g.bench_function(if noise { "noise" } else { "no_noise" }, |b| {
            b.iter(|| simulate(&spec).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
