//! The declared reach of effect parameters (`Effect::parameter_reach`), on which the
//! model check's grouped finite differences rely: a parameter declared to reach some
//! channels or excitations changes no other FRF, bit for bit, and (but for a gauge)
//! does change its own.

use crate::bench_recording::{nominal, recording, CASES};
use rbprops_check::candidates::candidates;
use rbprops_check::predict::{predict, Layout};
use rbprops_sim::effects::{Effect, Reach};

/// Every candidate of the bench's nominal spec, alone and with a channel gain, a sensor
/// misorientation, a force gauge's mass and a force direction switched on (effects that
/// rewrite output rows and inputs), at a point off its neutral one: each declared parameter, stepped, moves its own FRFs and no other.
#[test]
fn declared_reach_holds_for_every_candidate() {
    let spec = nominal();
    let (geometry, frf) = recording(CASES[0].0);
    let layout = Layout::new(&spec, &geometry, &frf).unwrap();
    let g = &layout.spec_geometry;
    let (cands, _) = candidates(&spec, g);
    let (nl, n_rch) = (layout.n_lines(), layout.channel_map.len());
    // Companions at a non-neutral point (the catalogue forms of the concealed effects).
    let off = |c: &rbprops_check::candidates::Candidate, k: usize| -> Vec<f64> {
        let info = c.effect.parameters();
        c.neutral
            .iter()
            .zip(&c.scales)
            .enumerate()
            .map(|(i, (n, s))| {
                let v = n + 0.7 * s * (((i + k) % 5) as f64 - 2.0);
                v.clamp(info[i].lower, info[i].upper)
            })
            .collect()
    };
    let companions: Vec<Box<dyn Effect>> = [
        "channel_gain",
        "sensor_misorientation",
        "force_gauge_mass",
        "force_direction",
    ]
    .iter()
    .map(|id| {
        let c = cands.iter().find(|c| c.id == *id).expect("candidate");
        c.effect.with_values(&off(c, 1)).unwrap()
    })
    .collect();
    let (mut declared, mut moving) = (0, 0);
    for c in &cands {
        let reach = c.effect.parameter_reach(g);
        assert_eq!(reach.len(), c.neutral.len(), "{}", c.id);
        let v = off(c, 0);
        let Ok(e0) = c.effect.with_values(&v) else {
            continue;
        };
        for with_companions in [false, true] {
            let others: Vec<Box<dyn Effect>> =
                if with_companions && !companions.iter().any(|x| x.id() == c.effect.id()) {
                    companions
                        .iter()
                        .map(|x| x.with_values(&x.values()).unwrap())
                        .collect()
                } else {
                    Vec::new()
                };
            let model = |e: Box<dyn Effect>| {
                let mut all: Vec<Box<dyn Effect>> = others
                    .iter()
                    .map(|x| x.with_values(&x.values()).unwrap())
                    .collect();
                all.push(e);
                predict(&spec, &layout, &all)
            };
            let Ok(m0) = model(e0.with_values(&v).unwrap()) else {
                continue;
            };
            for (j, r) in reach.iter().enumerate() {
                if *r == Reach::Any {
                    continue;
                }
                declared += 1;
                let mut w = v.clone();
                w[j] += c.scales[j];
                let m1 = model(c.effect.with_values(&w).unwrap()).unwrap();
                let mut moved = false;
                for (i, (a, b)) in m0.iter().zip(&m1).enumerate() {
                    let (ch, ex) = (
                        layout.channel_map[(i / nl) % n_rch],
                        layout.excitation_map[i / (nl * n_rch)],
                    );
                    if r.reaches(ch, ex) {
                        moved |= a != b;
                    } else {
                        assert_eq!(
                            (a.re.to_bits(), a.im.to_bits()),
                            (b.re.to_bits(), b.im.to_bits()),
                            "{} parameter {j} ({r:?}) moved value {i} (channel {ch}, excitation {ex})",
                            c.id
                        );
                    }
                }
                // A step along a gauge (a force moved along its own line) moves nothing.
                moving += usize::from(moved);
            }
        }
    }
    // The residues of the in-band resonance and of the residual flexibility, the channel
    // gains, misorientations and sensor offsets (27 + 27 + 9 + 9 + 9), the excitation
    // gains, force directions, locations and gauge masses (3 + 9 + 9 + 3), each twice.
    assert!(declared >= 2 * 105, "{declared} declared parameters tested");
    // And the declared parameters do move their own FRFs: all but the gauges.
    assert!(
        moving * 10 >= declared * 9,
        "{moving} of {declared} moved their FRFs"
    );
}
