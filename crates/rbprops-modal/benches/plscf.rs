//! Cost of one poly-reference fit (`Method::Plscf`: pLSCF sweep and selection, pole and
//! participation refinement, shapes, records) of a set-up of 3 excitations × 9 channels
//! × 1,000 lines (accelerance, 0–12.5 Hz, 1 % noise, the Test Case II body on springs,
//! built by `synthetic::test_case`), on one thread.
//!
//! `cargo bench -p rbprops-modal --bench plscf [-- repeats]` prints the median and the
//! minimum wall time per fit; with `--features phase-timing` also where the time goes
//! (`prof`'s phases as the poly-reference fit charges them: 0 sweep and selection,
//! 2 refinement, 6 shapes).

use rbprops_core::Quantity;
use rbprops_modal::{fit_campaign, prof, FitOptions, Method};
use rbprops_testkit::synthetic;
use std::time::Instant;

fn main() {
    // `cargo bench` passes `--bench`; the first number among the arguments is the count.
    let repeats: usize = std::env::args()
        .skip(1)
        .find_map(|s| s.parse().ok())
        .unwrap_or(31);
    let s = synthetic::test_case(12.5, 1000, Quantity::Accelerance).with_noise(0.01, 7);
    let opts = FitOptions {
        method: Method::Plscf,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut ms = Vec::with_capacity(repeats);
    let mut modes = 0;
    for _ in 0..repeats {
        let t = Instant::now();
        let out = pool.install(|| fit_campaign(&s.geometry, &s.frf, &opts).unwrap());
        ms.push(1e3 * t.elapsed().as_secs_f64());
        modes = out.record.modes.len() / s.frf.n_excitations;
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "plscf, {} excitations × {} channels × {} lines: median {:.2} ms, min {:.2} ms per fit over {repeats} fits ({modes} modes)",
        s.frf.n_excitations,
        s.frf.n_channels,
        s.frf.n_lines(),
        ms[ms.len() / 2],
        ms[0]
    );
    if let Some(totals) = prof::totals() {
        let names = [(0, "sweep and selection"), (2, "refinement"), (6, "shapes")];
        for (i, name) in names {
            let (calls, secs) = totals[i];
            println!(
                "  {name}: {:.2} ms per fit ({:.1} calls per fit)",
                1e3 * secs / repeats as f64,
                calls as f64 / repeats as f64
            );
        }
    }
}
