//! Planning speed: 200 candidate points (each a sensor position and a hit along its
//! face's inward normal, `tests/data/test-case-2-candidates.csv`), 4 sensors, 6 hits, on
//! Test Case II with 1 % FRF noise. `cargo bench -p rbprops-plan --bench plan_speed`.

use rbprops_core::Vec3;
use rbprops_plan::{plan, Candidates, Hit, PlanModel, PlanOptions, Sensor};

fn main() {
    let mut spec = rbprops_sim::CampaignSpec::from_toml_str(
        rbprops_sim::example("test-case-2").expect("example"),
    )
    .expect("spec");
    spec.noise.relative = 0.01;
    let model = PlanModel::from_spec(&spec).expect("model");
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/test-case-2-candidates.csv"
    );
    let text = std::fs::read_to_string(path).expect("candidates");
    let mut c = Candidates::default();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let n = |i: usize| f[i].parse::<f64>().expect("number");
        let p = Vec3::new(n(1), n(2), n(3));
        c.sensors.push(Sensor::triaxial(f[0], p));
        c.hits.push(Hit {
            id: f[0].to_string(),
            position: p,
            direction: Vec3::new(n(5), n(6), n(7)),
            setup: 0,
        });
    }
    let opts = PlanOptions {
        sensors: 4,
        hits: 6,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let out = plan(&model, &c, 0, &opts).expect("plan");
    let dt = t.elapsed().as_secs_f64();
    println!(
        "plan_speed: {} candidates, 4 sensors, 6 hits: {dt:.2} s on {} threads, {} layouts evaluated, criterion {:.3}",
        c.sensors.len(),
        rayon::current_num_threads(),
        out.evaluations,
        out.value
    );
}
