//! Wider vector instructions for hot loops, chosen at run time.
//!
//! The workspace is compiled for the baseline x86-64 (SSE2: two f64 lanes). The hot
//! loops (the LSCF sums and factor recursion, the LSFD basis, the per-line 6×6 solves
//! of a batch of lines, the extra modes' sums, the lag scan) are written as independent
//! lanes of plain additions, multiplications and divisions; compiled with AVX they run
//! four lanes per instruction. The results are bitwise the same: AVX adds, multiplies
//! and divides are the same IEEE operations as SSE2's, the order of every sum is fixed
//! by the source, and FMA (one rounding instead of two) is not enabled.

/// Defines a function whose body is compiled twice, for the baseline and with AVX, the
/// AVX copy running when the CPU has it (`is_x86_feature_detected!` is a cached load).
/// Plain (non-generic, no `self`) functions with named arguments only; the return type
/// may be left out.
///
/// ```
/// rbprops_core::avx_fn! {
///     /// `Σ xᵢ yᵢ`, in order.
///     pub fn dot(x: &[f64], y: &[f64]) -> f64 {
///         x.iter().zip(y).fold(0.0, |s, (a, b)| s + a * b)
///     }
/// }
/// assert_eq!(dot(&[1.0, 2.0], &[3.0, 4.0]), 11.0);
/// ```
#[macro_export]
macro_rules! avx_fn {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $crate::avx_fn! { $(#[$m])* $vis fn $name($($arg: $ty),*) -> () $body }
    };
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) -> $ret {
            #[inline(always)]
            fn lanes($($arg: $ty),*) -> $ret $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx")]
                fn wide($($arg: $ty),*) -> $ret {
                    lanes($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: the CPU supports AVX (checked just above).
                    return unsafe { wide($($arg),*) };
                }
            }
            lanes($($arg),*)
        }
    };
}
