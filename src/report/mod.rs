//! What runs did, in numbers: summaries written beside a run's files (`summary.json`) and
//! benchmark tables set beside a paper's.
//!
//! * [`walk`]: one walk trial of Winkler 2015's pipeline summarized ([`walk::TrialReport`]),
//!   and the paper's Table I over randomized trials ([`walk::terrain_benchmark`]).

pub mod walk;
