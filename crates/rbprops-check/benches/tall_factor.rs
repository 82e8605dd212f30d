//! Per-call cost of the tall factorisations and products the check runs on its
//! Jacobians (108 000 rows, as the six-effects bench's 1 000 lines × 9 channels × 6
//! excitations, real and imaginary parts): `r_factor` (the R of a thin QR, the score
//! tests' and the Wald statistic's) beside `gram` (JᵀJ, the same columns' normal matrix)
//! for 1 to 60 columns. Run with `RAYON_NUM_THREADS=1` for one core's figures:
//! `RAYON_NUM_THREADS=1 cargo bench -p rbprops-check --bench tall_factor`.

use nalgebra::DMatrix;
use std::time::Instant;

const ROWS: usize = 108_000;
const REPEATS: usize = 15;

/// Median wall time of `REPEATS` calls of `f`, in ms.
fn median_ms(mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..REPEATS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[REPEATS / 2]
}

fn main() {
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut draw = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    println!("columns  r_factor (ms)  gram (ms)  ratio");
    for p in [1usize, 3, 6, 12, 27, 60] {
        let a = DMatrix::from_fn(ROWS, p, |_, _| draw());
        let cols: Vec<usize> = (0..p).collect();
        let unit = vec![1.0; p];
        let r = median_ms(|| {
            std::hint::black_box(rbprops_check::lm::r_factor(&a, &cols, &unit));
        });
        let g = median_ms(|| {
            std::hint::black_box(rbprops_check::lm::gram(&a));
        });
        println!("{p:7}  {r:13.2}  {g:9.2}  {:5.1}", r / g);
    }
}
