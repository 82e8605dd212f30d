//! Peaks of an indicator curve, ranked by topographic prominence.

/// A local maximum of a curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Index of the peak's line on the curve.
    pub line: usize,
    /// Height above the higher of the two valleys that separate it from higher ground
    /// (or from the ends of the curve), in the curve's units.
    pub prominence: f64,
}

/// Interior local maxima (`y[i−1] < y[i] ≥ y[i+1]`, the first line of a plateau) with
/// prominence ≥ `min_prominence`, in ascending line order. End points are not peaks:
/// a curve rising to the band edge shows a mode outside the band, not in it.
pub fn find_peaks(y: &[f64], min_prominence: f64) -> Vec<Peak> {
    let n = y.len();
    let mut out = Vec::new();
    if n < 3 {
        return out;
    }
    for i in 1..n - 1 {
        if !(y[i] > y[i - 1]) {
            continue;
        }
        // Plateau: walk to its end; it is a peak if the curve then falls.
        let mut j = i;
        while j + 1 < n && y[j + 1] == y[i] {
            j += 1;
        }
        if j + 1 >= n || y[j + 1] > y[i] {
            continue;
        }
        let mut left_min = y[i];
        let mut k = i;
        while k > 0 {
            k -= 1;
            if y[k] > y[i] {
                break;
            }
            left_min = left_min.min(y[k]);
        }
        let mut right_min = y[i];
        let mut k = j;
        while k + 1 < n {
            k += 1;
            if y[k] > y[i] {
                break;
            }
            right_min = right_min.min(y[k]);
        }
        let prominence = y[i] - left_min.max(right_min);
        if prominence >= min_prominence {
            out.push(Peak {
                line: i,
                prominence,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prominence_is_measured_to_the_higher_valley() {
        //        0    1    2    3    4    5    6    7    8
        let y = [0.0, 5.0, 1.0, 3.0, 2.0, 9.0, 4.0, 4.0, 0.0];
        let p = find_peaks(&y, 0.0);
        assert_eq!(
            p,
            vec![
                Peak {
                    line: 1,
                    prominence: 4.0
                },
                Peak {
                    line: 3,
                    prominence: 1.0
                },
                Peak {
                    line: 5,
                    prominence: 9.0
                },
            ]
        );
        assert_eq!(find_peaks(&y, 2.0).len(), 2);
        // Monotone curves and end points have no peaks; plateaus count once.
        assert!(find_peaks(&[1.0, 2.0, 3.0], 0.0).is_empty());
        let plateau = find_peaks(&[0.0, 2.0, 2.0, 2.0, 1.0], 0.0);
        assert_eq!(
            plateau,
            vec![Peak {
                line: 1,
                prominence: 1.0
            }]
        );
    }
}
