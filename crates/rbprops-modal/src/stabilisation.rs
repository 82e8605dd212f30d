//! Stabilisation diagram and automatic pole selection.
//!
//! Classification (per order, against the nearest physical pole of the previous
//! order): frequency-stable when `|Δf|/f < tol_f`, damping-stable when `|Δζ|/ζ < tol_ζ`,
//! shape-stable when `1 − MAC < tol_φ`; stable = all three.
//!
//! Selection clusters the poles that are frequency stable and damping or shape stable
//! (a cluster needs at least one fully stable pole). The distance between two poles is measured in
//! half-power half-bandwidths `ζω_r` of the narrower one (relative to the data, not a
//! fixed Hz window) and two poles with dissimilar shapes never join. A cluster takes at
//! most one pole per model order: two poles that the *same* model separates are two
//! modes, however close, so close modes are never merged. Clusters present in too few
//! orders are computational and rejected.

use crate::lscf::OrderPoles;
use crate::options::StabilisationTolerances;
use crate::pole::{mac, Pole};
use rbprops_core::c64;

/// Stability class of a pole in the diagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StabilityClass {
    /// Physical (decaying, in band) but not stable against the previous order.
    New,
    /// Frequency stable only.
    Frequency,
    /// Frequency and damping stable.
    Damping,
    /// Frequency and shape stable.
    Shape,
    /// Frequency, damping and shape stable.
    Stable,
    /// Rejected outright: unstable (growing), overdamped or outside the band.
    Computational,
}

impl StabilityClass {
    /// The letter drawn for this class in the diagram.
    pub fn symbol(self) -> &'static str {
        match self {
            StabilityClass::New => "o",
            StabilityClass::Frequency => "f",
            StabilityClass::Damping => "d",
            StabilityClass::Shape => "v",
            StabilityClass::Stable => "s",
            StabilityClass::Computational => "x",
        }
    }
}

/// One point of the stabilisation diagram.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagramPole {
    /// Model order (denominator degree) the pole was found at.
    pub order: usize,
    /// Natural frequency (Hz).
    pub frequency_hz: f64,
    /// Damping ratio (fraction of critical).
    pub damping_ratio: f64,
    /// Stability against the next lower order.
    pub class: StabilityClass,
    /// Index of the selected mode (0-based, ascending frequency) this pole supports.
    pub mode: Option<usize>,
}

/// The stabilisation diagram of one excitation (or set-up): plot data.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StabilisationDiagram {
    /// Every pole of every order.
    pub poles: Vec<DiagramPole>,
    /// Highest model order computed.
    pub max_order: usize,
}

/// A selected mode: representative pole and shape, and how sure the selection is.
#[derive(Debug, Clone)]
pub struct SelectedPole {
    /// Representative pole of the cluster.
    pub pole: Pole,
    /// Representative shape (relative residues per channel, for MAC).
    pub shape: Vec<c64>,
    /// Stable poles supporting it.
    pub support: usize,
    /// Fraction of orders (from its first appearance) in which it is stable.
    pub presence: f64,
    /// Standard deviation of (f Hz, ζ) over the supporting poles: the scatter of the
    /// estimate across model orders, used as its uncertainty when not refined.
    pub spread: (f64, f64),
}

/// Output of the selection.
#[derive(Debug, Clone)]
pub struct Selection {
    /// The diagram, with each pole's selected mode.
    pub diagram: StabilisationDiagram,
    /// The selected modes, ascending frequency.
    pub modes: Vec<SelectedPole>,
    /// Rejected clusters with at least two poles, best supported first: candidates for
    /// a residual-driven model-order test (a weak mode next to a strong one).
    pub candidates: Vec<SelectedPole>,
    /// Selection warnings (e.g. fewer stable clusters than asked for).
    pub warnings: Vec<String>,
}

fn physical(p: &Pole, band_w: (f64, f64), tol: &StabilisationTolerances) -> bool {
    let z = p.damping();
    let w = p.omega_n();
    z > 0.0 && z < tol.max_damping && w >= band_w.0 && w <= band_w.1
}

/// (diagram index, order index, pole index) of a pole that may join a cluster.
type PoleRef = (usize, usize, usize);

/// Poles of successive model orders that the clustering groups as one mode.
struct Cluster {
    anchor: Pole,
    shape: Vec<c64>,
    members: Vec<PoleRef>,
    lowest_order: usize,
}

/// Classifies every pole and selects the physical modes.
///
/// `band_w` is the band in rad/s. `n_modes` forces the number of modes (the best
/// supported clusters are kept).
pub fn select(
    orders: &[OrderPoles],
    band_w: (f64, f64),
    tol: &StabilisationTolerances,
    n_modes: Option<usize>,
) -> Selection {
    let (mut diagram, stable) = classify(orders, band_w, tol);
    let clusters = cluster_stable_poles(orders, &stable, tol);
    let ranking = ClusterRanking {
        orders,
        clusters: &clusters,
        diagram: &diagram,
    };
    let mut warnings = Vec::new();
    let keep = ranking.kept_clusters(tol, n_modes, &mut warnings);
    let mut modes: Vec<(usize, SelectedPole)> =
        keep.iter().map(|&ci| (ci, ranking.summarise(ci))).collect();
    let candidates = ranking.candidates(&keep, &modes, band_w, tol);
    modes.sort_by(|a, b| a.1.pole.omega_n().total_cmp(&b.1.pole.omega_n()));
    for (mi, (ci, _)) in modes.iter().enumerate() {
        for &(di, _, _) in &clusters[*ci].members {
            diagram.poles[di].mode = Some(mi);
        }
    }
    Selection {
        diagram,
        modes: modes.into_iter().map(|m| m.1).collect(),
        candidates,
        warnings,
    }
}

/// Builds the diagram: every pole of every order, classified against the nearest
/// physical pole of the previous order. Also returns the poles that may join a cluster.
fn classify(
    orders: &[OrderPoles],
    band_w: (f64, f64),
    tol: &StabilisationTolerances,
) -> (StabilisationDiagram, Vec<PoleRef>) {
    let mut diagram = StabilisationDiagram {
        poles: Vec::new(),
        max_order: orders.iter().map(|o| o.order).max().unwrap_or(0),
    };
    let mut stable: Vec<PoleRef> = Vec::new();
    // Per order, each pole's natural frequency and whether it is physical, computed once
    // (the comparisons below would otherwise recompute them for every pair of poles).
    let props: Vec<Vec<(f64, bool)>> = orders
        .iter()
        .map(|op| {
            op.poles
                .iter()
                .map(|p| (p.omega_n(), physical(p, band_w, tol)))
                .collect()
        })
        .collect();
    for (oi, op) in orders.iter().enumerate() {
        for (pi, p) in op.poles.iter().enumerate() {
            let class = if !props[oi][pi].1 {
                StabilityClass::Computational
            } else if oi > 0 {
                class_against_previous(orders, &props, oi, pi, tol)
            } else {
                StabilityClass::New
            };
            // Clusters are built from poles stable in frequency and in damping or shape;
            // a cluster must contain at least one fully stable pole to be kept. With noise
            // the damping of a real mode wanders more between orders than its frequency
            // and shape, so requiring all three everywhere would starve real modes.
            if matches!(
                class,
                StabilityClass::Stable | StabilityClass::Shape | StabilityClass::Damping
            ) {
                stable.push((diagram.poles.len(), oi, pi));
            }
            diagram.poles.push(DiagramPole {
                order: op.order,
                frequency_hz: p.frequency_hz(),
                damping_ratio: p.damping(),
                class,
                mode: None,
            });
        }
    }
    (diagram, stable)
}

/// Stability class of physical pole `pi` of order `oi` (> 0) against the nearest (in
/// natural frequency) physical pole of order `oi − 1`; `props` holds each pole's
/// natural frequency and physicality.
fn class_against_previous(
    orders: &[OrderPoles],
    props: &[Vec<(f64, bool)>],
    oi: usize,
    pi: usize,
    tol: &StabilisationTolerances,
) -> StabilityClass {
    let (op, prev) = (&orders[oi], &orders[oi - 1]);
    let p = &op.poles[pi];
    let wp = props[oi][pi].0;
    let pp = &props[oi - 1];
    let best = prev
        .poles
        .iter()
        .enumerate()
        .filter(|(qi, _)| pp[*qi].1)
        .min_by(|a, b| {
            let da = (pp[a.0].0 - wp).abs();
            let db = (pp[b.0].0 - wp).abs();
            da.total_cmp(&db)
        });
    match best {
        None => StabilityClass::New,
        Some((qi, q)) => {
            let df = (q.omega_n() - p.omega_n()).abs() / p.omega_n();
            let dz = (q.damping() - p.damping()).abs() / p.damping();
            let dm = 1.0 - mac(&op.shapes[pi], &prev.shapes[qi]);
            match (df < tol.frequency, dz < tol.damping, dm < tol.shape) {
                (false, _, _) => StabilityClass::New,
                (true, true, true) => StabilityClass::Stable,
                (true, true, false) => StabilityClass::Damping,
                (true, false, true) => StabilityClass::Shape,
                (true, false, false) => StabilityClass::Frequency,
            }
        }
    }
}

/// Groups the `stable` poles into clusters, highest orders first (their poles are the
/// best converged). Each order's poles are matched to the clusters greedily, nearest
/// (in half-power bandwidths) first, at most one pole per cluster and order; a pole
/// left unmatched starts a new cluster.
fn cluster_stable_poles(
    orders: &[OrderPoles],
    stable: &[PoleRef],
    tol: &StabilisationTolerances,
) -> Vec<Cluster> {
    let mut clusters: Vec<Cluster> = Vec::new();
    for oi in (0..orders.len()).rev() {
        let here: Vec<&PoleRef> = stable.iter().filter(|s| s.1 == oi).collect();
        // All candidate (distance, pole, cluster) pairs, then greedy smallest-first.
        let mut pairs = Vec::new();
        for (a, s) in here.iter().enumerate() {
            let p = &orders[oi].poles[s.2];
            for (ci, c) in clusters.iter().enumerate() {
                let d = p.distance_in_bandwidths(&c.anchor);
                let shape_ok = 1.0 - mac(&orders[oi].shapes[s.2], &c.shape) < 5.0 * tol.shape;
                if d < tol.cluster_bandwidths && shape_ok {
                    pairs.push((d, a, ci));
                }
            }
        }
        pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let mut pole_used = vec![false; here.len()];
        let mut cluster_used = vec![false; clusters.len()];
        for (_, a, ci) in pairs {
            if pole_used[a] || cluster_used[ci] {
                continue;
            }
            pole_used[a] = true;
            cluster_used[ci] = true;
            clusters[ci].members.push(*here[a]);
            clusters[ci].lowest_order = orders[oi].order;
        }
        for (a, s) in here.iter().enumerate() {
            if !pole_used[a] {
                clusters.push(Cluster {
                    anchor: orders[oi].poles[s.2],
                    shape: orders[oi].shapes[s.2].clone(),
                    members: vec![**s],
                    lowest_order: orders[oi].order,
                });
            }
        }
    }
    clusters
}

/// The clusters with what is needed to judge them: their support across the orders of
/// the diagram and whether they hold a fully stable pole.
struct ClusterRanking<'a> {
    orders: &'a [OrderPoles],
    clusters: &'a [Cluster],
    diagram: &'a StabilisationDiagram,
}

impl ClusterRanking<'_> {
    /// Orders of the diagram from `lowest` up (the sweep may skip orders, e.g. odd ones).
    fn orders_from(&self, lowest: usize) -> usize {
        self.orders
            .iter()
            .filter(|o| o.order >= lowest)
            .count()
            .max(1)
    }

    /// Indices of the clusters kept as modes: those present in enough orders with
    /// enough poles or, when `n_modes` forces the count, the best supported ones
    /// (a warning when fewer are available).
    fn kept_clusters(
        &self,
        tol: &StabilisationTolerances,
        n_modes: Option<usize>,
        warnings: &mut Vec<String>,
    ) -> Vec<usize> {
        let n_orders = self.orders.len().max(1);
        let min_support = 3usize.max(n_orders / 8);
        let fully_stable = |c: &Cluster| {
            c.members
                .iter()
                .any(|&(di, _, _)| self.diagram.poles[di].class == StabilityClass::Stable)
        };
        // (cluster, presence, support) of the clusters with a fully stable pole.
        let mut ranked: Vec<(usize, f64, usize)> = self
            .clusters
            .iter()
            .enumerate()
            .filter(|(_, c)| fully_stable(c))
            .map(|(ci, c)| {
                let span = self.orders_from(c.lowest_order);
                (ci, c.members.len() as f64 / span as f64, c.members.len())
            })
            .collect();
        match n_modes {
            None => ranked
                .iter()
                .filter(|(_, pres, n)| *pres >= tol.min_presence && *n >= min_support)
                .map(|r| r.0)
                .collect(),
            Some(k) => {
                ranked.sort_by(|a, b| b.2.cmp(&a.2).then(b.1.total_cmp(&a.1)).then(a.0.cmp(&b.0)));
                if ranked.len() < k {
                    warnings.push(format!(
                        "{k} modes requested but the stabilisation diagram shows only {} stable pole clusters",
                        ranked.len()
                    ));
                }
                ranked.iter().take(k).map(|r| r.0).collect()
            }
        }
    }

    /// Cluster `ci` as a selected pole: its highest-order member (first pushed) is the
    /// representative, the scatter of its members across the orders the spread.
    fn summarise(&self, ci: usize) -> SelectedPole {
        let orders = self.orders;
        let c = &self.clusters[ci];
        let (_, oi, pi) = c.members[0];
        let span = self.orders_from(c.lowest_order);
        let fz: Vec<(f64, f64)> = c
            .members
            .iter()
            .map(|&(_, oi, pi)| {
                let p = orders[oi].poles[pi];
                (p.frequency_hz(), p.damping())
            })
            .collect();
        let nf = fz.len() as f64;
        let (mf, mz) = fz
            .iter()
            .fold((0.0, 0.0), |a, b| (a.0 + b.0 / nf, a.1 + b.1 / nf));
        let var = fz.iter().fold((0.0, 0.0), |a, b| {
            (a.0 + (b.0 - mf).powi(2) / nf, a.1 + (b.1 - mz).powi(2) / nf)
        });
        SelectedPole {
            pole: orders[oi].poles[pi],
            shape: orders[oi].shapes[pi].clone(),
            support: c.members.len(),
            presence: (c.members.len() as f64 / span as f64).min(1.0),
            spread: (var.0.sqrt(), var.1.sqrt()),
        }
    }

    /// Candidates for a residual-driven model-order test: the best supported rejected
    /// clusters of at least two poles (up to four), then the physical poles of the
    /// highest order that no kept or candidate cluster explains (up to six in all): a
    /// weak mode beside a strong one may appear only there.
    fn candidates(
        &self,
        keep: &[usize],
        modes: &[(usize, SelectedPole)],
        band_w: (f64, f64),
        tol: &StabilisationTolerances,
    ) -> Vec<SelectedPole> {
        let clusters = self.clusters;
        let mut rest: Vec<usize> = (0..clusters.len())
            .filter(|ci| !keep.contains(ci) && clusters[*ci].members.len() >= 2)
            .collect();
        rest.sort_by(|&a, &b| {
            clusters[b]
                .members
                .len()
                .cmp(&clusters[a].members.len())
                .then(a.cmp(&b))
        });
        let mut candidates: Vec<SelectedPole> =
            rest.iter().take(4).map(|&ci| self.summarise(ci)).collect();
        if let Some(top) = self.orders.last() {
            for (pi, p) in top.poles.iter().enumerate() {
                if candidates.len() >= 6 || !physical(p, band_w, tol) {
                    continue;
                }
                let near = modes
                    .iter()
                    .map(|m| &m.1.pole)
                    .chain(candidates.iter().map(|c| &c.pole))
                    .any(|q| q.distance_in_bandwidths(p) < tol.cluster_bandwidths);
                if !near {
                    candidates.push(SelectedPole {
                        pole: *p,
                        shape: top.shapes[pi].clone(),
                        support: 1,
                        presence: 1.0 / self.orders_from(top.order) as f64,
                        spread: (0.0, 0.0),
                    });
                }
            }
        }
        candidates
    }
}
