mod common;
use rbprops_uq::*;

#[test]
#[ignore]
fn explore() {
    let t0 = std::time::Instant::now();
    let c = common::case("demo", 3, None);
    eprintln!("pipeline {:?}", t0.elapsed());
    let t0 = std::time::Instant::now();
    let (out, boot) = solve_with_bootstrap(
        &c.geometry,
        &c.modal,
        &c.selection,
        &c.frf,
        &c.solve_opts,
        &BootstrapOptions {
            replicates: 20,
            ..Default::default()
        },
    )
    .unwrap();
    eprintln!("bootstrap {:?}", t0.elapsed());
    let boot = boot.unwrap();
    eprintln!(
        "pole mode {:?}; warnings {:?}",
        boot.pole_mode, out.warnings
    );
    for n in &boot.noise {
        eprintln!(
            "{} {:?}",
            n.excitation,
            n.channels
                .iter()
                .map(|c| (c.relative, c.floor))
                .collect::<Vec<_>>()
        );
    }
    let tv = common::truth_vector(&c.truth);
    for b in &boot.estimates {
        eprintln!("{} failed {} {:?}", b.method, b.failed, b.failure_reasons);
        for k in 0..10 {
            eprintln!(
                "  {:4} est {:+.6e} truth {:+.6e} z {:+.2} std {:.3e} bias {:+.3e}",
                PROPERTY_NAMES[k],
                b.estimate[k],
                tv[k],
                (b.estimate[k] - tv[k]) / b.std[k],
                b.std[k],
                b.bias[k]
            );
        }
    }
    for e in &out.estimates {
        eprintln!("{} {}", e.method, e.uncertainty_method);
    }
}
