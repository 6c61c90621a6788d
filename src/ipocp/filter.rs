//! The filter of IPOCP's line search (Wächter & Biegler 2006, sec. 2.3): pairs
//! `(theta, phi)` of constraint violation and barrier objective that a trial point must not
//! be dominated by.

/// A filter: a trial `(theta, phi)` is acceptable if, against every entry, it has a
/// smaller violation or a smaller barrier objective (eq. 21).
#[derive(Clone, Debug, Default)]
pub(crate) struct Filter {
    entries: Vec<(f64, f64)>,
    /// Upper bound on the violation, `theta_max` (sec. 2.3: `1e4 max(1, theta_0)`).
    pub theta_max: f64,
}

impl Filter {
    pub fn reset(&mut self) {
        self.entries.clear();
    }

    pub fn acceptable(&self, theta: f64, phi: f64) -> bool {
        theta <= self.theta_max && self.entries.iter().all(|&(t, p)| theta < t || phi < p)
    }

    /// Adds `(theta, phi)` and drops the entries it dominates.
    pub fn add(&mut self, theta: f64, phi: f64) {
        self.entries.retain(|&(t, p)| t < theta || p < phi);
        self.entries.push((theta, phi));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominated_points_are_rejected() {
        let mut f = Filter { theta_max: 10.0, ..Default::default() };
        f.add(1.0, 5.0);
        assert!(f.acceptable(0.5, 6.0));
        assert!(f.acceptable(2.0, 4.0));
        assert!(!f.acceptable(1.5, 5.5));
        assert!(!f.acceptable(11.0, 0.0));
        f.add(0.5, 4.0); // dominates (1, 5)
        assert!(!f.acceptable(0.9, 4.5));
        assert_eq!(f.entries.len(), 1);
    }
}
