//! The merge scorers: `paper` (Appeal of eq. 5 with the matching and boundary filters) and the
//! ablations of the paper's Table 1 (`no-benefit-cost`, `no-size-bonus`, `random`), plus
//! `seam-edges` (the reference fork's variant without the boundary filter).

use scanatlas_core::plugin::{
    MergeScorer, OpFeatures, ParamInfo, ParamValue, Params, PluginError, PluginInfo, PluginKind,
    Registry, Score, Veto, get_f64,
};
use scanatlas_core::rng::SplitMix64;

/// Which terms of eq. 5 a scorer keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Variant {
    Paper,
    NoBenefitCost,
    NoSizeBonus,
    Random,
    SeamEdges,
}

/// A scorer of the paper family; the variant picks the terms of the appeal.
#[derive(Clone, Debug)]
pub struct PaperScorer {
    variant: Variant,
    /// m: the mean alignment error may be at most m times the mean seam-side length.
    matching_tolerance: f64,
    /// b: an inter-chart merge must dissolve at least this fraction of one chart's perimeter.
    boundary_tolerance: f64,
    seed: u64,
}

/// The filters shared by every variant, in the reference's order: zero area, boundary, matching.
fn filters(s: &PaperScorer, op: &OpFeatures) -> Option<Veto> {
    let areas = [op.uv_area_a, op.uv_area_b, op.area_3d_a, op.area_3d_b];
    if areas.iter().any(|a| !(a.is_finite() && *a > 0.0)) {
        return Some(Veto::ZeroArea);
    }
    if s.variant != Variant::SeamEdges
        && op.inter_chart
        && benefit(op) < s.boundary_tolerance
        && !op.island_lookahead
    {
        return Some(Veto::Boundary);
    }
    let mean_side = 0.5 * (op.seam_length_a + op.seam_length_b);
    if !op.mean_match_error.is_finite() || op.mean_match_error > s.matching_tolerance * mean_side {
        return Some(Veto::Matching);
    }
    None
}

/// Benefit (eq. 1): the larger fraction of a chart's perimeter that the merge dissolves; a zero
/// perimeter (impossible for a real chart) counts as no benefit rather than a division by zero.
fn benefit(op: &OpFeatures) -> f64 {
    let frac = |l: f64, p: f64| if p > 0.0 && l.is_finite() { l / p } else { 0.0 };
    frac(op.seam_length_a, op.perimeter_a).max(frac(op.seam_length_b, op.perimeter_b))
}

/// A seeded, platform-independent hash for the `random` ablation: the first draw of a SplitMix64
/// stream started at `x`.
fn splitmix(x: u64) -> u64 {
    SplitMix64::new(x).next_u64()
}

/// Turns the reference's cost (1/Appeal) into a finite appeal. A perfect match has cost 0 and the
/// highest appeal; once it has failed, the reference resets its cost to 1 before the back-off so it
/// does not stay first forever (digest §4.2 step 8).
fn appeal_from_cost(cost: f64, failures: u32) -> f64 {
    let backoff = 2f64.powi(failures.min(1000) as i32);
    let cost = if cost == 0.0 && failures > 0 { 1.0 } else { cost };
    let cost = cost * backoff;
    if cost > 0.0 && cost.is_finite() {
        (1.0 / cost).min(f64::MAX)
    } else if cost == 0.0 {
        f64::MAX
    } else {
        0.0
    }
}

impl MergeScorer for PaperScorer {
    fn score(&self, op: &OpFeatures) -> Score {
        if let Some(v) = filters(self, op) {
            return Score::Veto(v);
        }
        let min_area = op.uv_area_a.min(op.uv_area_b);
        let b = benefit(op);
        let cost = match self.variant {
            // Appeal = Benefit / Cost · SizeBonus · BackOff  (eq. 5).
            Variant::Paper => {
                if b <= 0.0 {
                    return Score::Veto(Veto::Boundary);
                }
                op.mean_match_error / b * min_area
            }
            // NoBC: only SizeBonus · BackOff.
            Variant::NoBenefitCost => min_area,
            // NoSB: only Benefit / Cost · BackOff.
            Variant::NoSizeBonus => {
                if b <= 0.0 {
                    return Score::Veto(Veto::Boundary);
                }
                op.mean_match_error / b
            }
            Variant::SeamEdges => op.mean_match_error / op.seam_edges.max(1) as f64 * min_area,
            Variant::Random => {
                let h =
                    splitmix(self.seed ^ splitmix(((op.op_id as u64) << 32) | op.failures as u64));
                // Uniform in (0, 1]: never zero, so the appeal stays finite.
                let u = ((h >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
                return Score::Appeal(u);
            }
        };
        let cost = if cost.is_finite() { cost } else { f64::INFINITY };
        Score::Appeal(appeal_from_cost(cost, op.failures))
    }
}

fn common_params() -> Vec<ParamInfo> {
    vec![
        ParamInfo {
            name: "matching-tolerance",
            default: ParamValue::Float(2.0),
            help: "m: maximum mean alignment error, in multiples of the mean seam-side length",
        },
        ParamInfo {
            name: "boundary-tolerance",
            default: ParamValue::Float(0.2),
            help: "b: minimum fraction of one chart's perimeter an inter-chart merge must dissolve",
        },
    ]
}

fn info(name: &'static str, summary: &'static str, extra: Vec<ParamInfo>) -> PluginInfo {
    let mut params = common_params();
    params.extend(extra);
    PluginInfo { kind: PluginKind::Scorer, name, summary, params }
}

fn build(variant: Variant, info: &PluginInfo, params: &Params) -> Result<PaperScorer, PluginError> {
    let m = get_f64(params, info, "matching-tolerance")?;
    let b = get_f64(params, info, "boundary-tolerance")?;
    let bad = |param: &str, msg: &str| PluginError::BadParam {
        kind: info.kind,
        name: info.name.to_string(),
        param: param.to_string(),
        msg: msg.to_string(),
    };
    if m < 0.0 {
        return Err(bad("matching-tolerance", "must be ≥ 0"));
    }
    if !(0.0..=1.0).contains(&b) {
        return Err(bad("boundary-tolerance", "must be within 0..=1"));
    }
    let seed = if info.params.iter().any(|p| p.name == "seed") {
        get_f64(params, info, "seed")? as u64
    } else {
        0
    };
    Ok(PaperScorer { variant, matching_tolerance: m, boundary_tolerance: b, seed })
}

/// Registers every scorer of this module.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let table: [(Variant, PluginInfo); 5] = [
        (
            Variant::Paper,
            info(
                "paper",
                "Appeal = Benefit/Cost · SizeBonus · BackOff (eq. 5) with the m and b filters",
                vec![],
            ),
        ),
        (
            Variant::NoBenefitCost,
            info(
                "no-benefit-cost",
                "Ablation NoBC: SizeBonus · BackOff only (filters kept)",
                vec![],
            ),
        ),
        (
            Variant::NoSizeBonus,
            info(
                "no-size-bonus",
                "Ablation NoSB: Benefit/Cost · BackOff only (filters kept)",
                vec![],
            ),
        ),
        (
            Variant::Random,
            info(
                "random",
                "Ablation: seeded random order (filters kept)",
                vec![ParamInfo {
                    name: "seed",
                    default: ParamValue::Int(0),
                    help: "seed of the order",
                }],
            ),
        ),
        (
            Variant::SeamEdges,
            info(
                "seam-edges",
                "Mean error per dissolved edge · SizeBonus · BackOff, no boundary filter",
                vec![],
            ),
        ),
    ];
    for (variant, info) in table {
        let captured = info.clone();
        registry.register_scorer(info, move |p| {
            Ok(Box::new(build(variant, &captured, p)?) as Box<dyn MergeScorer>)
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn op() -> OpFeatures {
        OpFeatures {
            op_id: 3,
            inter_chart: true,
            uv_area_a: 400.0,
            uv_area_b: 25.0,
            area_3d_a: 1.0,
            area_3d_b: 0.1,
            perimeter_a: 80.0,
            perimeter_b: 20.0,
            seam_length_a: 10.0,
            seam_length_b: 10.0,
            mean_match_error: 0.5,
            pairs: 6,
            seam_edges: 5,
            failures: 0,
            island_lookahead: false,
        }
    }

    fn scorer(name: &str) -> Box<dyn MergeScorer> {
        let mut r = Registry::default();
        register(&mut r).unwrap();
        r.scorer(name, &Params::new()).unwrap()
    }

    #[test]
    fn paper_appeal_is_eq_5() {
        // Benefit = max(10/80, 10/20) = 0.5; Cost = 0.5; SizeBonus = 1/25; BackOff = 1.
        let s = scorer("paper");
        assert_eq!(s.score(&op()), Score::Appeal(0.5 / 0.5 / 25.0));
        let failed = OpFeatures { failures: 2, ..op() };
        assert_eq!(s.score(&failed), Score::Appeal(0.5 / 0.5 / 25.0 / 4.0));
    }

    #[test]
    fn filters_veto_in_the_reference_order() {
        let s = scorer("paper");
        assert_eq!(s.score(&OpFeatures { uv_area_b: 0.0, ..op() }), Score::Veto(Veto::ZeroArea));
        assert_eq!(
            s.score(&OpFeatures { area_3d_a: f64::NAN, ..op() }),
            Score::Veto(Veto::ZeroArea)
        );
        let thin = OpFeatures { seam_length_a: 1.0, seam_length_b: 1.0, ..op() };
        assert_eq!(s.score(&thin), Score::Veto(Veto::Boundary));
        assert!(matches!(
            s.score(&OpFeatures { island_lookahead: true, ..thin }),
            Score::Appeal(_)
        ));
        let intra_thin = OpFeatures { inter_chart: false, ..thin };
        assert!(
            matches!(s.score(&intra_thin), Score::Appeal(_)),
            "boundary filter is inter-chart only"
        );
        assert_eq!(
            s.score(&OpFeatures { mean_match_error: 20.5, ..op() }),
            Score::Veto(Veto::Matching)
        );
        assert!(matches!(
            s.score(&OpFeatures { mean_match_error: 20.0, ..op() }),
            Score::Appeal(_)
        ));
    }

    #[test]
    fn perfect_matches_rank_first_but_back_off_once_failed() {
        let s = scorer("paper");
        assert_eq!(s.score(&OpFeatures { mean_match_error: 0.0, ..op() }), Score::Appeal(f64::MAX));
        let failed = OpFeatures { mean_match_error: 0.0, failures: 1, ..op() };
        assert_eq!(s.score(&failed), Score::Appeal(0.5));
    }

    #[test]
    fn every_appeal_is_finite_and_non_negative() {
        for name in ["paper", "no-benefit-cost", "no-size-bonus", "random", "seam-edges"] {
            let s = scorer(name);
            for e in [0.0, 1e-300, 1e-3, 1.0, 1e300] {
                for k in [0, 1, 60, 5000] {
                    let o =
                        OpFeatures { mean_match_error: e, failures: k, uv_area_b: 1e-300, ..op() };
                    if let Score::Appeal(a) = s.score(&o) {
                        assert!(a.is_finite() && a >= 0.0, "{name}: {a}");
                    }
                }
            }
        }
    }

    #[test]
    fn ablations_drop_their_terms_and_random_is_seeded() {
        assert_eq!(scorer("no-benefit-cost").score(&op()), Score::Appeal(1.0 / 25.0));
        assert_eq!(scorer("no-size-bonus").score(&op()), Score::Appeal(0.5 / 0.5));
        let r = scorer("random");
        assert_eq!(r.score(&op()), r.score(&op()));
        assert_ne!(r.score(&op()), r.score(&OpFeatures { op_id: 4, ..op() }));
        let mut reg = Registry::default();
        register(&mut reg).unwrap();
        let mut p = Params::new();
        p.insert("seed".into(), ParamValue::Int(9));
        assert_ne!(reg.scorer("random", &p).unwrap().score(&op()), r.score(&op()));
    }

    #[test]
    fn registry_refuses_unknown_names_params_and_duplicates() {
        let mut r = Registry::default();
        register(&mut r).unwrap();
        let err = r.scorer("papr", &Params::new()).err().unwrap().to_string();
        assert!(err.contains("paper") && err.contains("random"), "{err}");
        let mut p = Params::new();
        p.insert("alpha".into(), ParamValue::Float(1.0));
        let err = r.scorer("paper", &p).err().unwrap().to_string();
        assert!(err.contains("matching-tolerance"), "{err}");
        assert!(matches!(register(&mut r), Err(PluginError::Duplicate { .. })));
        p.clear();
        p.insert("boundary-tolerance".into(), ParamValue::Float(2.0));
        assert!(matches!(r.scorer("paper", &p), Err(PluginError::BadParam { .. })));
    }
}
