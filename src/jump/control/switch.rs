//! The switch from the jumping to the landing controller (Nguyen 2022, sec. III):
//!
//! ```text
//! if (any c_s >= delta) & (t >= T_posing) then switch to landing controller
//! ```
//!
//! with `c_s` the contact sensor of foot `s` (here the normal force the simulator reports)
//! and `delta` the force threshold of an impact. Once switched, the landing controller
//! stays on; each foot counts as in contact from its first reading at or above `delta`
//! (Remark 2: a swing leg is held until "the ground contact is detected on these legs"). A
//! foot stays in contact after that: at impact a foot bounces for a few milliseconds, and
//! switching its leg between the QP and the swing PD at 1 kHz would only add the jolts.

/// The switch state, one flag per foot.
#[derive(Clone, Debug, PartialEq)]
pub struct LandingSwitch {
    /// `delta` (N).
    threshold: f64,
    /// `T_posing` (s).
    t_posing: f64,
    switched_at: Option<f64>,
    in_contact: Vec<bool>,
}

impl LandingSwitch {
    pub fn new(threshold: f64, t_posing: f64, feet: usize) -> Self {
        Self { threshold, t_posing, switched_at: None, in_contact: vec![false; feet] }
    }

    /// Reads the sensors `forces` (N, one per foot) at time `t`; returns whether the
    /// landing controller is on.
    pub fn update(&mut self, t: f64, forces: &[f64]) -> bool {
        if self.switched_at.is_none() && t >= self.t_posing && forces.iter().any(|&c| c >= self.threshold) {
            self.switched_at = Some(t);
        }
        if self.switched_at.is_some() {
            for (contact, &c) in self.in_contact.iter_mut().zip(forces) {
                *contact |= c >= self.threshold;
            }
        }
        self.switched_at.is_some()
    }

    /// When the landing controller took over (s).
    pub fn switched_at(&self) -> Option<f64> {
        self.switched_at
    }

    /// Per foot: contact detected since the switch (all `false` before it).
    pub fn in_contact(&self) -> &[bool] {
        &self.in_contact
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_switch_before_t_posing_even_under_load() {
        let mut s = LandingSwitch::new(20.0, 0.5, 4);
        // Take-off: all four feet loaded well above the threshold.
        assert!(!s.update(0.0, &[40.0; 4]));
        assert!(!s.update(0.499, &[100.0, 0.0, 0.0, 0.0]));
        assert_eq!(s.switched_at(), None);
        assert_eq!(s.in_contact(), &[false; 4]);
    }

    #[test]
    fn switches_on_the_first_foot_at_the_threshold_and_latches_contacts() {
        let mut s = LandingSwitch::new(20.0, 0.5, 4);
        assert!(!s.update(0.6, &[19.999, 0.0, 5.0, 0.0]));
        assert!(s.update(0.601, &[20.0, 0.0, 5.0, 0.0]));
        assert_eq!(s.switched_at(), Some(0.601));
        assert_eq!(s.in_contact(), &[true, false, false, false]);
        // The first foot bounces off, the third touches: both count as in contact.
        assert!(s.update(0.602, &[0.0, 0.0, 30.0, 0.0]));
        assert_eq!(s.in_contact(), &[true, false, true, false]);
        assert_eq!(s.switched_at(), Some(0.601));
    }
}
