//! Property tests: the no_std learner against a plain std reference written separately here
//! (Vec-based, straight from the formulas of the paper and DESIGN section 4), bit for bit on
//! random streams; and finiteness of the weights for any in-bound input.

use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FEATURE_BOUND, FEATURE_COUNT, Feature, FeatureTable,
    Feedback, Learner, LearnerKind, LearnerParams, MAX_ACTIONS, MAX_STEP, OnlineLearner, Polarity,
    PreferenceFeedback, Round, SemanticFeedback, Statement, WEIGHT_BOUND,
};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// The reference: vectors, loops, no shared code with the crate.

struct RefLearner {
    kind: LearnerKind,
    step: f32,
    radius: Option<f32>,
    w: Vec<f32>,
    avg: Vec<f32>,
    squares: Vec<f32>,
    t: u32,
}

enum RefFeedback {
    Action(usize),
    Preference(usize, usize),
    /// (feature, wants a higher value), and the path reference (x, y, heading) a statement about
    /// the path is judged against (by the cross-track error of each trajectory's end).
    Semantic(Vec<(usize, bool)>, Option<(f32, f32, f32)>),
}

/// The cross-track error of trajectory `a`'s end against the path through `(x, y)` with heading
/// `h`: the distance from the end to that line, `|(e − p) × (cos h, sin h)|`. The sine and cosine
/// are `libm::sincosf`'s, as the car's; everything else is written out here.
fn rcross(a: usize, (x, y, h): (f32, f32, f32)) -> f32 {
    let e = firmware_core::lattice::trajectory(ActionIndex::new(a).unwrap()).end();
    let (s, c) = libm::sincosf(h);
    ((e.y - y) * c - (e.x - x) * s).abs()
}

/// The path feature's index, written out (the order of DESIGN section 5).
const PATH: usize = 4;

fn rdot(a: &[f32], b: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for i in 0..a.len() {
        s += a[i] * b[i];
    }
    s
}

fn rdist(a: &[f32], b: &[f32]) -> f32 {
    let mut s = 0.0f32;
    for i in 0..a.len() {
        s += (a[i] - b[i]) * (a[i] - b[i]);
    }
    s.sqrt()
}

impl RefLearner {
    fn new(kind: LearnerKind, step: f32, radius: Option<f32>, init: &[f32]) -> Self {
        RefLearner {
            kind,
            step,
            radius,
            w: init.to_vec(),
            avg: init.to_vec(),
            squares: vec![0.0; init.len()],
            t: 0,
        }
    }

    fn acting(&self) -> &[f32] {
        if self.kind == LearnerKind::AveragedOgd {
            &self.avg
        } else {
            &self.w
        }
    }

    fn select(&self, phi: &[Vec<f32>], allowed: &[usize]) -> usize {
        let mut best = allowed[0];
        for &a in allowed {
            if rdot(self.acting(), &phi[a]) > rdot(self.acting(), &phi[best]) {
                best = a;
            }
        }
        best
    }

    /// Applies feedback; returns false when the crate must refuse it (weights untouched).
    fn learn(
        &mut self,
        phi: &[Vec<f32>],
        allowed: &[usize],
        chosen: usize,
        fb: &RefFeedback,
    ) -> bool {
        // Pseudo-loss over the allowed actions.
        let mut delta = vec![0.0f32; MAX_ACTIONS];
        for &a in allowed {
            delta[a] = match fb {
                RefFeedback::Action(t) => {
                    if a == *t {
                        0.0
                    } else {
                        100.0
                    }
                }
                RefFeedback::Preference(p, np) => {
                    rdist(&phi[*p], &phi[a]) - rdist(&phi[*np], &phi[a])
                }
                RefFeedback::Semantic(stmts, reference) => {
                    let mut v = 0.0f32;
                    for &(f, higher) in stmts {
                        let (va, vc) = match (f, reference) {
                            (PATH, Some(r)) => (rcross(a, *r), rcross(chosen, *r)),
                            (PATH, None) => return false,
                            _ => (phi[a][f], phi[chosen][f]),
                        };
                        let better = if higher { va > vc } else { va < vc };
                        if !better {
                            v += 100.0;
                        }
                    }
                    v
                }
            };
        }
        let min = allowed
            .iter()
            .map(|&a| delta[a])
            .fold(f32::INFINITY, f32::min);
        for &a in allowed {
            delta[a] -= min;
        }
        // The point where the subgradient is taken: averaged OGD takes absolute (action) feedback
        // at its raw iterate, relative feedback at its average (the acting weights).
        let absolute = matches!(fb, RefFeedback::Action(_));
        let at: Vec<f32> = if self.kind == LearnerKind::AveragedOgd && absolute {
            self.w.clone()
        } else {
            self.acting().to_vec()
        };
        // â: smallest Δ, then highest score, then lowest index.
        let mut hat = allowed[0];
        for &a in allowed {
            let (da, dh) = (delta[a], delta[hat]);
            if da < dh || (da == dh && rdot(&at, &phi[a]) > rdot(&at, &phi[hat])) {
                hat = a;
            }
        }
        let sel = if self.kind == LearnerKind::Coactive {
            chosen
        } else {
            let s_hat = rdot(&at, &phi[hat]);
            let mut sel = hat;
            let mut best = 0.0f32;
            for &a in allowed {
                if a != hat {
                    let v = delta[a] + (rdot(&at, &phi[a]) - s_hat);
                    if v > best {
                        best = v;
                        sel = a;
                    }
                }
            }
            sel
        };
        if sel == hat {
            return true;
        }
        let g: Vec<f32> = (0..FEATURE_COUNT)
            .map(|i| phi[sel][i] - phi[hat][i])
            .collect();
        if g.iter().any(|x| x.abs() > 2.0 * FEATURE_BOUND) {
            return false;
        }
        let t = self.t + 1;
        let mut w = self.w.clone();
        let mut squares = self.squares.clone();
        for i in 0..FEATURE_COUNT {
            match self.kind {
                LearnerKind::OgdDecaying => w[i] -= self.step / (t as f32).sqrt() * g[i],
                LearnerKind::AdaGrad => {
                    squares[i] += g[i] * g[i];
                    w[i] -= self.step * g[i] / (squares[i].sqrt() + 1.0e-6);
                }
                _ => w[i] -= self.step * g[i],
            }
        }
        if let Some(r) = self.radius {
            let n = w.iter().map(|x| x * x).fold(0.0f32, |s, x| s + x).sqrt();
            if n > r {
                let k = r / n;
                w.iter_mut().for_each(|x| *x *= k);
            }
        }
        let ok = |v: &[f32]| v.iter().all(|x| x.is_finite() && x.abs() <= WEIGHT_BOUND);
        if !ok(&w) {
            return false;
        }
        let mut avg = self.avg.clone();
        if self.kind == LearnerKind::AveragedOgd {
            for i in 0..FEATURE_COUNT {
                avg[i] += (w[i] - avg[i]) / (t as f32 + 1.0);
            }
            if !ok(&avg) {
                return false;
            }
        }
        self.w = w;
        self.avg = avg;
        self.squares = squares;
        self.t = t;
        true
    }
}

// ---------------------------------------------------------------------------------------------
// Random streams.

#[derive(Clone, Debug)]
struct RoundSpec {
    features: Vec<f32>,
    mask: u64,
    kind: u8,
    i: u8,
    j: u8,
    statements: [u8; FEATURE_COUNT],
    reference: Option<(f32, f32, f32)>,
}

fn feature_value() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -10.0f32..10.0,
        1 => -FEATURE_BOUND..=FEATURE_BOUND,
        1 => Just(0.0f32),
        1 => (-3i32..=3).prop_map(|x| x as f32),
    ]
}

fn round_spec() -> impl Strategy<Value = RoundSpec> {
    (
        proptest::collection::vec(feature_value(), MAX_ACTIONS * FEATURE_COUNT),
        prop_oneof![
            Just(u64::MAX),
            any::<u64>().prop_map(|m| m | 1 << (m % 64)),
            (0u32..64).prop_map(|b| 1u64 << b)
        ],
        0u8..3,
        any::<u8>(),
        any::<u8>(),
        any::<[u8; FEATURE_COUNT]>(),
        prop_oneof![
            1 => Just(None),
            3 => (-5.0f32..=5.0, -5.0f32..=5.0, -core::f32::consts::PI..=core::f32::consts::PI)
                .prop_map(Some),
        ],
    )
        .prop_map(
            |(features, mask, kind, i, j, statements, reference)| RoundSpec {
                features,
                mask,
                kind,
                i,
                j,
                statements,
                reference,
            },
        )
}

/// The round of `b` with the spec's path reference, if it has one.
fn round<'a>(spec: &RoundSpec, b: &'a Built, chosen: ActionIndex) -> Round<'a> {
    let r = Round::new(&b.table, b.mask, chosen).unwrap();
    match spec.reference {
        Some((x, y, heading)) => r.with_reference(PathReference { x, y, heading }).unwrap(),
        None => r,
    }
}

fn learner_params() -> impl Strategy<Value = LearnerParams> {
    (
        proptest::sample::select(LearnerKind::ALL.to_vec()),
        prop_oneof![
            Just(None),
            Just(Some(0.01f32)),
            (1.0e-4f32..MAX_STEP).prop_map(Some)
        ],
        prop_oneof![3 => Just(None), 1 => (0.1f32..100.0).prop_map(Some)],
        proptest::array::uniform6(-1.0f32..1.0),
    )
        .prop_map(|(kind, step, radius, initial)| {
            let mut p = LearnerParams::new(kind).with_initial(initial);
            if let Some(s) = step {
                p = p.with_step(s);
            }
            if let Some(r) = radius {
                p = p.with_radius(r.max(2.5)); // the initial weights lie inside a ball of 2.45
            }
            p
        })
}

struct Built {
    table: FeatureTable,
    mask: ActionMask,
    allowed: Vec<usize>,
    phi: Vec<Vec<f32>>,
}

fn build(spec: &RoundSpec) -> Built {
    let mut table = FeatureTable::ZERO;
    let mut phi = vec![vec![0.0f32; FEATURE_COUNT]; MAX_ACTIONS];
    for a in 0..MAX_ACTIONS {
        for f in 0..FEATURE_COUNT {
            let v = spec.features[a * FEATURE_COUNT + f];
            table[ActionIndex::new(a).unwrap()][f] = v;
            phi[a][f] = v;
        }
    }
    let mask = ActionMask::from_bits(spec.mask);
    let allowed = (0..MAX_ACTIONS)
        .filter(|a| spec.mask >> a & 1 == 1)
        .collect();
    Built {
        table,
        mask,
        allowed,
        phi,
    }
}

fn feedback(spec: &RoundSpec, allowed: &[usize], chosen: usize) -> (Feedback, RefFeedback) {
    let pick = |x: u8| allowed[x as usize % allowed.len()];
    let idx = |x| ActionIndex::new(x).unwrap();
    match spec.kind {
        0 => {
            let t = pick(spec.i);
            (
                ActionFeedback { action: idx(t) }.into(),
                RefFeedback::Action(t),
            )
        }
        1 => {
            let (p, np) = (chosen, pick(spec.j));
            let (p, np) = if spec.i.is_multiple_of(2) {
                (p, np)
            } else {
                (np, p)
            };
            (
                PreferenceFeedback {
                    preferred: idx(p),
                    other: idx(np),
                }
                .into(),
                RefFeedback::Preference(p, np),
            )
        }
        _ => {
            let mut s = SemanticFeedback::new();
            let mut r = Vec::new();
            for (f, &code) in spec.statements.iter().enumerate() {
                let polarity = match code % 3 {
                    0 => continue,
                    1 => Polarity::Avoid,
                    _ => Polarity::Prefer,
                };
                let st = Statement {
                    subject: Feature::from_index(f).unwrap(),
                    polarity,
                };
                s = s.with(st);
                r.push((f, st.wants_higher()));
            }
            (s.into(), RefFeedback::Semantic(r, spec.reference))
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 192, ..ProptestConfig::default() })]

    /// The crate and the reference choose the same actions and hold bit-identical weights after
    /// every round of a random stream, for every learner and every kind of feedback.
    #[test]
    fn learner_equals_the_std_reference(
        params in learner_params(),
        stream in proptest::collection::vec(round_spec(), 1..24),
    ) {
        let mut learner = Learner::new(params.check().unwrap());
        let mut reference = RefLearner::new(params.kind, params.step, params.radius, &params.initial);
        for spec in &stream {
            let b = build(spec);
            let chosen = learner.select(&b.table, b.mask).unwrap();
            prop_assert_eq!(chosen.get(), reference.select(&b.phi, &b.allowed));
            let (fb, rfb) = feedback(spec, &b.allowed, chosen.get());
            let round = round(spec, &b, chosen);
            let got = learner.learn(&round, &fb);
            let degenerate = matches!(&rfb, RefFeedback::Preference(p, np) if p == np)
                || matches!(&rfb, RefFeedback::Semantic(s, _) if s.is_empty());
            if degenerate {
                prop_assert!(got.is_err());
                continue;
            }
            let accepted = reference.learn(&b.phi, &b.allowed, chosen.get(), &rfb);
            prop_assert_eq!(got.is_ok(), accepted, "{:?}", got);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(learner.weights()), bits(reference.acting()));
            prop_assert_eq!(learner.steps(), reference.t);
        }
    }

    /// Whatever finite, in-bound features and feedback arrive, the weights stay finite and within
    /// WEIGHT_BOUND; a refused call leaves them exactly as they were.
    #[test]
    fn weights_stay_finite(
        params in learner_params(),
        stream in proptest::collection::vec(round_spec(), 1..40),
    ) {
        let mut learner = Learner::new(params.check().unwrap());
        for spec in &stream {
            let b = build(spec);
            let chosen = learner.select(&b.table, b.mask).unwrap();
            let (fb, _) = feedback(spec, &b.allowed, chosen.get());
            let round = round(spec, &b, chosen);
            let before = learner;
            if learner.learn(&round, &fb).is_err() {
                prop_assert_eq!(learner, before);
            }
            prop_assert!(learner.weights().iter().all(|x| x.is_finite() && x.abs() <= WEIGHT_BOUND));
        }
    }

    /// Non-finite features are refused before anything is read.
    #[test]
    fn non_finite_features_are_refused(spec in round_spec(), bad in prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY), Just(1.0e5f32)], at in 0usize..MAX_ACTIONS * FEATURE_COUNT) {
        let mut b = build(&spec);
        let action = ActionIndex::new(at / FEATURE_COUNT).unwrap();
        b.table[action][at % FEATURE_COUNT] = bad;
        let chosen = b.mask.first().unwrap();
        let r = Round::new(&b.table, b.mask, chosen);
        prop_assert_eq!(r.is_err(), b.mask.contains(action));
    }

    /// A snapshot restores a learner that continues bit-identically.
    #[test]
    fn snapshot_round_trips(params in learner_params(), stream in proptest::collection::vec(round_spec(), 1..8)) {
        let mut learner = Learner::new(params.check().unwrap());
        for spec in &stream {
            let b = build(spec);
            let chosen = learner.select(&b.table, b.mask).unwrap();
            let (fb, _) = feedback(spec, &b.allowed, chosen.get());
            let _ = learner.learn(&round(spec, &b, chosen), &fb);
        }
        let bytes = postcard::to_allocvec(&learner.snapshot()).unwrap();
        let back: firmware_core::LearnerSnapshot = postcard::from_bytes(&bytes).unwrap();
        prop_assert_eq!(Learner::restore(&back).unwrap(), learner);
    }
}
