//! Matching the modes identified per excitation into physical modes of one set-up, by
//! frequency and MAC of their rigid-body shapes.
//!
//! Each identified mode's residues are reduced to the rigid motion `q = (SᵀS)⁻¹SᵀA`
//! (paper Eq. 5). MAC is taken on the rigid-body shapes at the channels, `S q`:
//! `MAC(a, b) = (q_aᵀ W q_b)² / ((q_aᵀ W q_a)(q_bᵀ W q_b))` with `W = SᵀS`. Unlike MAC on
//! the raw 6-vector it does not depend on the units of rotation versus translation or on
//! the choice of origin; unlike MAC on mass-normalised shapes it needs no mass matrix
//! (which is what we want to estimate).

use rbprops_core::{Mat6, Vec6};

/// MAC of two rigid motions in the metric `w` (`SᵀS`); 0 when either is null.
pub fn mac(a: &Vec6, b: &Vec6, w: &Mat6) -> f64 {
    let ab = (a.transpose() * w * b)[0];
    let aa = (a.transpose() * w * a)[0];
    let bb = (b.transpose() * w * b)[0];
    if aa > 0.0 && bb > 0.0 {
        (ab * ab / (aa * bb)).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// What the matcher needs to know of one identified mode.
#[derive(Debug, Clone)]
pub(crate) struct Candidate {
    /// Position of its excitation in the geometry.
    pub excitation: usize,
    pub frequency_hz: f64,
    pub q: Vec6,
    /// `f_kᵀq`, used to pick a group's reference shape.
    pub strength: f64,
    /// Well excited and above the noise: its shape can be trusted for MAC.
    pub reliable: bool,
}

/// Matching tolerances.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MatchTolerances {
    pub mac_threshold: f64,
    /// Largest relative frequency difference `|f_a − f_b| / f_b` of one physical mode.
    pub frequency_tolerance: f64,
}

/// Weight of the frequency term against MAC in the pair score. Small: inside the
/// tolerance, MAC decides (near-repeated modes have nearly equal frequencies, and the
/// per-excitation estimates may even swap their order).
const FREQUENCY_WEIGHT: f64 = 0.25;

/// The group member whose shape stands for the group: reliable first, then strongest.
pub(crate) fn reference_member(group: &[usize], cands: &[Candidate]) -> usize {
    *group
        .iter()
        .max_by(|&&a, &&b| {
            (cands[a].reliable, cands[a].strength)
                .partial_cmp(&(cands[b].reliable, cands[b].strength))
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(b.cmp(&a))
        })
        .expect("groups are never empty")
}

/// Score of assigning candidate `c` to a group whose reference is `r`, or `None` if not
/// allowed. Every allowed score is ≥ 0.5 so that the optimum also maximises the number of
/// matches before the quality of the matches.
fn pair_score(c: &Candidate, r: &Candidate, w: &Mat6, tol: &MatchTolerances) -> Option<f64> {
    let df = (c.frequency_hz - r.frequency_hz).abs() / r.frequency_hz.abs().max(f64::MIN_POSITIVE);
    if !(df <= tol.frequency_tolerance) {
        return None;
    }
    let m = mac(&c.q, &r.q, w);
    // A weakly excited estimate's shape is mostly noise: it joins by frequency.
    if c.reliable && r.reliable && m < tol.mac_threshold {
        return None;
    }
    let x = df / tol.frequency_tolerance;
    Some(1.0 + m - FREQUENCY_WEIGHT * x * x)
}

/// Best one-to-one assignment of `members` (rows) to `groups` (columns) maximising the
/// summed score; exact (bitmask dynamic programme) up to 16 groups, greedy beyond.
fn assign(scores: &[Vec<Option<f64>>], n_groups: usize) -> Vec<Option<usize>> {
    let n = scores.len();
    if n_groups <= 16 {
        let states = 1usize << n_groups;
        // best[i][mask]: best total for members i.. with groups in `mask` already used.
        let mut best = vec![vec![0.0f64; states]; n + 1];
        for i in (0..n).rev() {
            for mask in 0..states {
                let mut b = best[i + 1][mask];
                for (g, s) in scores[i].iter().enumerate() {
                    if let Some(s) = s {
                        if mask & (1 << g) == 0 {
                            b = b.max(s + best[i + 1][mask | (1 << g)]);
                        }
                    }
                }
                best[i][mask] = b;
            }
        }
        let mut out = vec![None; n];
        let mut mask = 0usize;
        for i in 0..n {
            let target = best[i][mask];
            if target == best[i + 1][mask] {
                continue;
            }
            for (g, s) in scores[i].iter().enumerate() {
                if let Some(s) = s {
                    if mask & (1 << g) == 0 && s + best[i + 1][mask | (1 << g)] == target {
                        out[i] = Some(g);
                        mask |= 1 << g;
                        break;
                    }
                }
            }
        }
        out
    } else {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, row) in scores.iter().enumerate() {
            for (g, s) in row.iter().enumerate() {
                if let Some(s) = s {
                    pairs.push((*s, i, g));
                }
            }
        }
        pairs.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut out = vec![None; n];
        let mut used = vec![false; n_groups];
        for (_, i, g) in pairs {
            if out[i].is_none() && !used[g] {
                out[i] = Some(g);
                used[g] = true;
            }
        }
        out
    }
}

/// Groups the candidates into physical modes. Excitations are visited from the one with
/// the most reliable modes down (ties: geometry order); the first seeds the groups, each
/// next one is assigned optimally to the groups so far, and what does not match starts a
/// new group. Returns groups of candidate indices, ascending in reference frequency.
pub(crate) fn match_candidates(
    cands: &[Candidate],
    w: &Mat6,
    tol: &MatchTolerances,
) -> Vec<Vec<usize>> {
    let mut excitations: Vec<usize> = cands.iter().map(|c| c.excitation).collect();
    excitations.sort_unstable();
    excitations.dedup();
    let reliable_count = |k: usize| {
        cands
            .iter()
            .filter(|c| c.excitation == k && c.reliable)
            .count()
    };
    excitations.sort_by(|&a, &b| reliable_count(b).cmp(&reliable_count(a)).then(a.cmp(&b)));

    let mut groups: Vec<Vec<usize>> = Vec::new();
    for k in excitations {
        let members: Vec<usize> = (0..cands.len())
            .filter(|&i| cands[i].excitation == k)
            .collect();
        let refs: Vec<usize> = groups.iter().map(|g| reference_member(g, cands)).collect();
        let scores: Vec<Vec<Option<f64>>> = members
            .iter()
            .map(|&i| {
                refs.iter()
                    .map(|&r| pair_score(&cands[i], &cands[r], w, tol))
                    .collect()
            })
            .collect();
        let assignment = assign(&scores, groups.len());
        for (&i, a) in members.iter().zip(assignment) {
            match a {
                Some(g) => groups[g].push(i),
                None => groups.push(vec![i]),
            }
        }
    }
    groups.sort_by(|a, b| {
        let fa = cands[reference_member(a, cands)].frequency_hz;
        let fb = cands[reference_member(b, cands)].frequency_hz;
        fa.total_cmp(&fb)
    });
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(k: usize, f: f64, q: [f64; 6], reliable: bool) -> Candidate {
        Candidate {
            excitation: k,
            frequency_hz: f,
            q: Vec6::from_row_slice(&q),
            strength: 1.0,
            reliable,
        }
    }

    #[test]
    fn mac_is_scale_invariant_and_zero_for_w_orthogonal() {
        let w = Mat6::identity();
        let a = Vec6::new(1.0, 2.0, 0.0, 0.0, 0.0, 0.0);
        assert!((mac(&a, &(a * -3.0), &w) - 1.0).abs() < 1e-15);
        assert_eq!(mac(&a, &Vec6::new(-2.0, 1.0, 0.0, 0.0, 0.0, 5.0), &w), 0.0);
        assert_eq!(mac(&a, &Vec6::zeros(), &w), 0.0);
    }

    #[test]
    fn assignment_prefers_mac_over_frequency_order() {
        let w = Mat6::identity();
        let tol = MatchTolerances {
            mac_threshold: 0.8,
            frequency_tolerance: 0.05,
        };
        let x = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let y = [0.0, 1.0, 0.0, 0.0, 0.1, 0.0];
        // Excitation 0 sees x at 1.000 and y at 1.004; excitation 1 sees them swapped in
        // frequency (x at 1.005, y at 0.999).
        let cands = vec![
            cand(0, 1.000, x, true),
            cand(0, 1.004, y, true),
            cand(1, 0.999, y, true),
            cand(1, 1.005, x, true),
        ];
        let g = match_candidates(&cands, &w, &tol);
        assert_eq!(g, vec![vec![0, 3], vec![1, 2]]);
        // Far in frequency: no match even with equal shapes.
        let far = vec![cand(0, 1.0, x, true), cand(1, 1.2, x, true)];
        assert_eq!(match_candidates(&far, &w, &tol).len(), 2);
        // An unreliable estimate joins by frequency despite a poor MAC.
        let weak = vec![cand(0, 1.0, x, true), cand(1, 1.01, y, false)];
        assert_eq!(match_candidates(&weak, &w, &tol), vec![vec![0, 1]]);
    }

    #[test]
    fn exact_and_greedy_assignments_agree_on_a_clear_case() {
        let scores = vec![
            vec![Some(1.9), Some(1.2), None],
            vec![Some(1.8), Some(1.1), Some(1.0)],
        ];
        // Exact: member 0 → group 0 would leave member 1 with group 1 (1.9+1.1 = 3.0);
        // member 0 → 1, member 1 → 0 gives 1.2+1.8 = 3.0 too; the first found is kept.
        let a = assign(&scores, 3);
        let total: f64 = a
            .iter()
            .enumerate()
            .map(|(i, g)| scores[i][g.unwrap()].unwrap())
            .sum();
        assert!((total - 3.0).abs() < 1e-12);
        assert_eq!(a.iter().flatten().count(), 2);
    }
}
