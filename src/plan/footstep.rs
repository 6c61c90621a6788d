//! The footstep sequence planner (Winkler 2015, sec. III-C): for every body action of the
//! body-action plan, a swing-leg order that depends on the action and, for each swing leg,
//! the foothold with the lowest foothold cost
//!
//! ```text
//! c_f = w_t c_t + w_st c_st + w_c c_c + w_o c_o
//! ```
//!
//! in a search area around the leg's nominal stance position after the action:
//!
//! * `c_t`, the terrain cost below the foothold (the cost map's, 1 = forbidden; legwork
//!   averages it over the foot's 3 x 3 cells, [`FootstepParams::foot_area_cells`]);
//! * `c_st`, the support-triangle cost: how much smaller than a wanted inscribed radius the
//!   triangle is on which the robot stands while the *next* leg swings;
//! * `c_c`, the leg-collision cost: how far the terrain along the straight swing path rises
//!   above the higher of lift-off and touch-down, relative to the swing height;
//! * `c_o`, the body-orientation cost: how far the foothold lies above or below the other
//!   three feet, which the body would have to roll or pitch to follow.
//!
//! To these legwork adds `w_n c_n`, `c_n = (|p - p_nominal| / half-width)^2`: the preference
//! for the nominal stance that centring the search area expresses in the paper, made a cost
//! so that the terrain cost's sensor noise (a few hundredths on flat ground) does not scatter
//! the footholds over the search area and shrink the support triangles.
//!
//! Any swing-leg order can come out of it; the ZMP body trajectory inserts four-leg support
//! where consecutive support triangles are disjoint.

use super::body::BodyPose;
use super::{costs_around, TerrainCostField};
use crate::model::description::LEG_ORDER;
use nalgebra::{Vector2, Vector3};

/// A body-frame point `(bx, by)` of the planar pose `pose` in the world.
pub fn body_to_world(pose: &BodyPose, b: [f64; 2]) -> Vector2<f64> {
    let (s, c) = pose.yaw.sin_cos();
    Vector2::new(pose.x + c * b[0] - s * b[1], pose.y + s * b[0] + c * b[1])
}


/// Leg indices, in the project's order (DESIGN.md).
pub const LF: usize = 0;
pub const RF: usize = 1;
pub const LH: usize = 2;
pub const RH: usize = 3;

/// Weights and limits of the footstep planner.
#[derive(Clone, Debug, PartialEq)]
pub struct FootstepParams {
    /// Nominal foot positions in the body frame (x, y), LF, RF, LH, RH.
    pub nominal: [[f64; 2]; 4],
    /// Half-width of the square search area around the nominal position (m).
    pub search_half_width: f64,
    /// Terrain cost at or above which a cell is never stepped on.
    pub forbidden_cost: f64,
    /// Wanted inscribed-circle radius of the support triangles (m).
    pub wanted_inscribed_radius: f64,
    /// Swing apex height above the higher end of the swing (m): the collision reference.
    pub swing_height: f64,
    /// Height difference to the other feet that counts as cost 1 for `c_o` (m).
    pub orientation_height: f64,
    /// Largest height difference between a foothold and the mean of the other three feet
    /// that the legs can reach (m): a foothold further up or down is not a candidate.
    pub max_step_height: f64,
    /// `w_t, w_st, w_c, w_o`.
    pub weights: [f64; 4],
    /// `w_n`, the weight of the distance from the nominal position.
    pub nominal_weight: f64,
    /// Radius (cells) of the square of cells whose mean terrain cost is `c_t` (0: the
    /// foothold's cell alone, as in the paper). The foot lands within about a cell of its
    /// target and then may roll or slide a little: its neighbours are where it can end up, and
    /// on a 16 cm stepping stone the cell next to the lip is the one to avoid.
    pub foot_area_cells: usize,
}

impl FootstepParams {
    /// HyQ's parameters around the nominal stance `nominal` (the body planner's
    /// [`super::body::NominalStance`], from the standing pose: x +-0.371, y +-0.324 on HyQ).
    pub fn hyq(nominal: [[f64; 2]; 4]) -> Self {
        Self {
            nominal,
            search_half_width: 0.12,
            forbidden_cost: 0.99,
            wanted_inscribed_radius: 0.12,
            swing_height: 0.1,
            orientation_height: 0.3,
            max_step_height: 0.25,
            weights: [1.0, 0.5, 1.0, 0.3],
            nominal_weight: 0.5,
            foot_area_cells: 1,
        }
    }
}

/// The terms of `c_f` and their weighted sum.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FootholdCost {
    pub terrain: f64,
    pub support: f64,
    pub collision: f64,
    pub orientation: f64,
    pub nominal: f64,
    pub total: f64,
}

/// One step: `leg` moves from `from` to `to` (surface points, world) while the body moves
/// toward `body` (the pose after the action the step belongs to).
#[derive(Clone, Debug, PartialEq)]
pub struct Footstep {
    pub leg: usize,
    pub from: Vector3<f64>,
    pub to: Vector3<f64>,
    /// Index of the body action this step belongs to.
    pub action: usize,
    pub body: BodyPose,
    pub cost: FootholdCost,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FootstepError {
    #[error("action {action}: no foothold for {leg} within {half_width} m of its nominal position ({x:.3}, {y:.3}) has a terrain cost below {forbidden} and a height the leg reaches")]
    NoFoothold { action: usize, leg: &'static str, x: f64, y: f64, half_width: f64, forbidden: f64 },
}

/// The swing-leg order for a body action `(dx, dy, dyaw)` in the body frame (sec. III-C:
/// "when moving left it is advantageous to swing one of the left legs"): a crawl that
/// starts with the hind leg on the side the body moves to, or with a front leg when the
/// body backs up.
pub fn swing_order(dx: f64, dy: f64, dyaw: f64) -> [usize; 4] {
    let lateral = dy.abs() > dx.abs();
    if lateral {
        if dy > 0.0 {
            [LH, LF, RH, RF]
        } else {
            [RH, RF, LH, LF]
        }
    } else if dx < -1e-9 {
        [LF, LH, RF, RH]
    } else if dx.abs() <= 1e-9 && dyaw < 0.0 {
        [RH, RF, LH, LF]
    } else {
        [LH, LF, RH, RF]
    }
}

/// Radius of the circle inscribed in the triangle `a, b, c` (0 for a degenerate one).
pub fn inscribed_radius(a: Vector2<f64>, b: Vector2<f64>, c: Vector2<f64>) -> f64 {
    let twice_area = ((b - a).perp(&(c - a))).abs();
    let perimeter = (b - a).norm() + (c - b).norm() + (a - c).norm();
    if perimeter <= 0.0 {
        0.0
    } else {
        twice_area / perimeter
    }
}

/// Plans the footsteps of the body path `body_path[0] -> body_path[1] -> ...` (one action
/// per consecutive pair) from the feet at `feet` (surface points, world, LF RF LH RH).
pub fn plan_footsteps(terrain: &dyn TerrainCostField, params: &FootstepParams, feet: [Vector3<f64>; 4], body_path: &[BodyPose]) -> Result<Vec<Footstep>, FootstepError> {
    let mut feet = feet;
    let mut steps = Vec::with_capacity(4 * body_path.len().saturating_sub(1));
    for (action, pair) in body_path.windows(2).enumerate() {
        let (before, after) = (pair[0], pair[1]);
        // The action in the body frame of `before`.
        let (s, c) = before.yaw.sin_cos();
        let (wx, wy) = (after.x - before.x, after.y - before.y);
        let order = swing_order(c * wx + s * wy, -s * wx + c * wy, after.yaw - before.yaw);
        for (i, &leg) in order.iter().enumerate() {
            let next_leg = order.get(i + 1).copied();
            let (to, cost) = best_foothold(terrain, params, &feet, leg, next_leg, after).ok_or_else(|| {
                let n = body_to_world(&after, params.nominal[leg]);
                FootstepError::NoFoothold { action, leg: LEG_ORDER[leg], x: n.x, y: n.y, half_width: params.search_half_width, forbidden: params.forbidden_cost }
            })?;
            steps.push(Footstep { leg, from: feet[leg], to, action, body: after, cost });
            feet[leg] = to;
        }
    }
    Ok(steps)
}

/// The lowest-`c_f` cell in the search area of `leg` around its nominal position at
/// `body`; ties go to the candidate nearest the nominal position.
fn best_foothold(terrain: &dyn TerrainCostField, params: &FootstepParams, feet: &[Vector3<f64>; 4], leg: usize, next_leg: Option<usize>, body: BodyPose) -> Option<(Vector3<f64>, FootholdCost)> {
    let nominal = body_to_world(&body, params.nominal[leg]);
    let r = terrain.resolution();
    let n = (params.search_half_width / r).floor() as i64;
    let others: Vec<usize> = (0..4).filter(|&l| l != leg).collect();
    let others_height = others.iter().map(|&l| feet[l].z).sum::<f64>() / 3.0;
    let [w_t, w_st, w_c, w_o] = params.weights;
    let mut best: Option<(Vector3<f64>, FootholdCost, f64)> = None;
    for i in -n..=n {
        for j in -n..=n {
            let (cx, cy) = terrain.cell_center(nominal.x + i as f64 * r, nominal.y + j as f64 * r);
            let p = Vector2::new(cx, cy);
            let c_cell = terrain.cost(p.x, p.y);
            if c_cell >= params.forbidden_cost || !c_cell.is_finite() {
                continue;
            }
            let c_t = foot_area_cost(terrain, p, params.foot_area_cells);
            let to = Vector3::new(p.x, p.y, terrain.height(p.x, p.y));
            if !to.z.is_finite() || (to.z - others_height).abs() > params.max_step_height {
                continue;
            }
            // c_st: the triangle the robot stands on while the next leg swings.
            let c_st = match next_leg {
                Some(next) => {
                    let corners: Vec<Vector2<f64>> = (0..4).filter(|&l| l != next).map(|l| if l == leg { p } else { feet[l].xy() }).collect();
                    let radius = inscribed_radius(corners[0], corners[1], corners[2]);
                    ((params.wanted_inscribed_radius - radius) / params.wanted_inscribed_radius).clamp(0.0, 1.0)
                }
                None => 0.0,
            };
            let c_c = swing_collision(terrain, &feet[leg], &to, params.swing_height);
            let c_o = ((to.z - others_height).abs() / params.orientation_height).min(1.0);
            let distance = (p - nominal).norm_squared();
            let c_n = distance / (params.search_half_width * params.search_half_width);
            let total = w_t * c_t + w_st * c_st + w_c * c_c + w_o * c_o + params.nominal_weight * c_n;
            let better = match &best {
                None => true,
                Some((_, b, d)) => total < b.total - 1e-12 || (total <= b.total + 1e-12 && distance < *d),
            };
            if better {
                best = Some((to, FootholdCost { terrain: c_t, support: c_st, collision: c_c, orientation: c_o, nominal: c_n, total }, distance));
            }
        }
    }
    best.map(|(to, cost, _)| (to, cost))
}

/// `c_t`: the mean terrain cost over the `(2 radius + 1)^2` cells centred on `p` (unknown or
/// non-finite cells count as forbidden, 1).
fn foot_area_cost(terrain: &dyn TerrainCostField, p: Vector2<f64>, radius: usize) -> f64 {
    let sum = costs_around(terrain, p.x, p.y, radius).fold(0.0, |sum, c| sum + if c.is_finite() { c.min(1.0) } else { 1.0 });
    sum / ((2 * radius + 1) * (2 * radius + 1)) as f64
}

/// `c_c`: the highest terrain along the straight swing path above the higher end, as a
/// fraction of the swing height (capped at 1).
fn swing_collision(terrain: &dyn TerrainCostField, from: &Vector3<f64>, to: &Vector3<f64>, swing_height: f64) -> f64 {
    let length = (to.xy() - from.xy()).norm();
    let samples = ((length / terrain.resolution()).ceil() as usize).max(1);
    let top = from.z.max(to.z);
    let mut rise: f64 = 0.0;
    for s in 1..samples {
        let p = from.xy() + (to.xy() - from.xy()) * (s as f64 / samples as f64);
        rise = rise.max(terrain.height(p.x, p.y) - top);
    }
    (rise / swing_height).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const HYQ_STANCE: [[f64; 2]; 4] = [[0.3708, 0.3241], [0.3708, -0.3241], [-0.3708, 0.3241], [-0.3708, -0.3241]];

    /// Flat ground at 0 with optional forbidden strips and raised boxes.
    struct TestTerrain {
        forbidden_x: Option<[f64; 2]>,
        boxes: Vec<([f64; 2], [f64; 2], f64)>,
    }

    impl TerrainCostField for TestTerrain {
        fn cost(&self, x: f64, _y: f64) -> f64 {
            match self.forbidden_x {
                Some([a, b]) if x >= a && x <= b => 1.0,
                _ => 0.0,
            }
        }
        fn height(&self, x: f64, y: f64) -> f64 {
            self.boxes.iter().filter(|(bx, by, _)| x >= bx[0] && x <= bx[1] && y >= by[0] && y <= by[1]).map(|b| b.2).fold(0.0, f64::max)
        }
        fn resolution(&self) -> f64 {
            0.04
        }
    }

    fn standing_feet(params: &FootstepParams, body: BodyPose) -> [Vector3<f64>; 4] {
        std::array::from_fn(|l| {
            let p = body_to_world(&body, params.nominal[l]);
            Vector3::new(p.x, p.y, 0.0)
        })
    }

    fn straight_path(step: f64, actions: usize) -> Vec<BodyPose> {
        (0..=actions).map(|k| BodyPose { x: k as f64 * step, y: 0.0, yaw: 0.0 }).collect()
    }

    #[test]
    fn flat_ground_gives_nominal_footholds_in_crawl_order() {
        let params = FootstepParams::hyq(HYQ_STANCE);
        let path = straight_path(0.2, 3);
        let steps = plan_footsteps(&TestTerrain { forbidden_x: None, boxes: vec![] }, &params, standing_feet(&params, path[0]), &path).unwrap();
        assert_eq!(steps.len(), 12);
        assert_eq!(steps.iter().take(4).map(|s| s.leg).collect::<Vec<_>>(), vec![LH, LF, RH, RF]);
        for s in &steps {
            let nominal = body_to_world(&s.body, params.nominal[s.leg]);
            // On a 4 cm grid the nominal point itself is a candidate.
            assert!((s.to.xy() - nominal).norm() < 1e-9, "{s:?}");
            assert_eq!(s.cost.terrain, 0.0);
            assert_eq!(s.cost.collision, 0.0);
        }
    }

    #[test]
    fn footholds_avoid_a_forbidden_strip() {
        let params = FootstepParams::hyq(HYQ_STANCE);
        let path = straight_path(0.15, 10);
        let strip = [0.9, 1.05];
        let steps = plan_footsteps(&TestTerrain { forbidden_x: Some(strip), boxes: vec![] }, &params, standing_feet(&params, path[0]), &path).unwrap();
        let mut displaced = 0;
        for s in &steps {
            assert!(s.to.x < strip[0] || s.to.x > strip[1], "{s:?}");
            let nominal = body_to_world(&s.body, params.nominal[s.leg]);
            if (s.to.xy() - nominal).norm() > 1e-9 {
                displaced += 1;
            }
        }
        // Some nominal footholds fall in the strip and were moved out of it.
        assert!(displaced >= 2, "{displaced}");
    }

    /// With `c_t` the mean over the foot's 3 x 3 cells, a foothold keeps a cell of usable
    /// ground between it and a forbidden strip when the nominal-distance cost allows; with
    /// the cell alone (the paper's `c_t`), footholds land right at the strip's edge.
    #[test]
    fn the_foot_area_keeps_footholds_a_cell_away_from_forbidden_ground() {
        let path = straight_path(0.15, 10);
        let strip = [0.9, 1.05];
        let terrain = TestTerrain { forbidden_x: Some(strip), boxes: vec![] };
        let at_edge = |params: &FootstepParams| {
            let steps = plan_footsteps(&terrain, params, standing_feet(params, path[0]), &path).unwrap();
            let r = terrain.resolution();
            steps.iter().filter(|s| [-r, r].iter().any(|dx| terrain.cost(s.to.x + dx, s.to.y) >= 1.0)).count()
        };
        let area = FootstepParams::hyq(HYQ_STANCE);
        assert_eq!(area.foot_area_cells, 1);
        let cell = FootstepParams { foot_area_cells: 0, ..area.clone() };
        let (with_area, with_cell) = (at_edge(&area), at_edge(&cell));
        assert_eq!(with_area, 0);
        assert!(with_cell >= 2, "{with_cell} footholds next to the strip with the cell-only cost");
    }

    #[test]
    fn a_pit_floor_out_of_the_legs_reach_is_never_a_foothold() {
        // A pit 0.5 m deep with cost 0 on its (flat) floor: only the reach limit excludes it.
        let params = FootstepParams::hyq(HYQ_STANCE);
        let path = straight_path(0.15, 10);
        let terrain = TestTerrain { forbidden_x: None, boxes: vec![([-5.0, 0.9], [-5.0, 5.0], 0.5), ([1.05, 9.0], [-5.0, 5.0], 0.5)] };
        let feet = standing_feet(&params, path[0]).map(|f| Vector3::new(f.x, f.y, 0.5));
        let steps = plan_footsteps(&terrain, &params, feet, &path).unwrap();
        assert!(steps.iter().all(|s| s.to.z == 0.5), "a foot went into the pit");
    }

    #[test]
    fn a_strip_wider_than_the_search_area_is_an_error_naming_the_action_and_leg() {
        let params = FootstepParams::hyq(HYQ_STANCE);
        let path = straight_path(0.2, 10);
        let e = plan_footsteps(&TestTerrain { forbidden_x: Some([0.8, 1.4]), boxes: vec![] }, &params, standing_feet(&params, path[0]), &path).unwrap_err();
        assert!(matches!(e, FootstepError::NoFoothold { .. }));
        assert!(e.to_string().contains("action"));
    }

    #[test]
    fn footholds_on_a_box_are_on_its_top() {
        let params = FootstepParams::hyq(HYQ_STANCE);
        let path = straight_path(0.2, 8);
        let pallet = ([1.0, 2.2], [-0.4, 0.4], 0.15);
        let terrain = TestTerrain { forbidden_x: None, boxes: vec![pallet] };
        let steps = plan_footsteps(&terrain, &params, standing_feet(&params, path[0]), &path).unwrap();
        for s in &steps {
            assert_eq!(s.to.z, terrain.height(s.to.x, s.to.y));
        }
        assert!(steps.iter().any(|s| s.to.z == 0.15));
    }

    #[test]
    fn swinging_over_a_ledge_costs_in_proportion_to_its_rise() {
        let terrain = TestTerrain { forbidden_x: None, boxes: vec![([1.0, 1.08], [-1.0, 1.0], 0.05)] };
        let over = swing_collision(&terrain, &Vector3::new(0.9, 0.0, 0.0), &Vector3::new(1.2, 0.0, 0.0), 0.1);
        assert!((over - 0.5).abs() < 1e-12, "{over}");
        let beside = swing_collision(&terrain, &Vector3::new(0.5, 0.0, 0.0), &Vector3::new(0.8, 0.0, 0.0), 0.1);
        assert_eq!(beside, 0.0);
        // Onto the ledge: nothing above the touch-down height.
        let onto = swing_collision(&terrain, &Vector3::new(0.9, 0.0, 0.0), &Vector3::new(1.04, 0.0, 0.05), 0.1);
        assert_eq!(onto, 0.0);
    }

    #[test]
    fn swing_order_follows_the_direction() {
        assert_eq!(swing_order(0.2, 0.0, 0.0), [LH, LF, RH, RF]);
        assert_eq!(swing_order(-0.2, 0.0, 0.0), [LF, LH, RF, RH]);
        assert_eq!(swing_order(0.0, 0.2, 0.0), [LH, LF, RH, RF]);
        assert_eq!(swing_order(0.0, -0.2, 0.0), [RH, RF, LH, LF]);
        assert_eq!(swing_order(0.0, 0.0, -0.3), [RH, RF, LH, LF]);
    }

    #[test]
    fn inscribed_radius_of_a_right_triangle() {
        // 3-4-5 triangle: r = (a + b - c) / 2 = 1.
        let r = inscribed_radius(Vector2::new(0.0, 0.0), Vector2::new(3.0, 0.0), Vector2::new(0.0, 4.0));
        assert!((r - 1.0).abs() < 1e-12);
        assert_eq!(inscribed_radius(Vector2::new(0.0, 0.0), Vector2::new(1.0, 0.0), Vector2::new(2.0, 0.0)), 0.0);
    }
}
