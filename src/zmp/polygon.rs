//! Support polygons and their stability margin (Winkler 2015, sec. IV-B, eq. 6 and Fig. 5).
//!
//! A support polygon is the convex hull of the stance feet projected on the ground plane
//! (three feet: the support triangle; four: the support quadrilateral of a four-leg support
//! phase). Eq. (6) writes "inside" as three (or four) linear conditions
//! `p_l x + q_l y + r_l > 0`, one per edge line `l`; [`EdgeLine`] is that line with
//! `(p, q)` the unit normal pointing into the polygon, so that `p x + q y + r` is the
//! distance of an inside point to the line. Shrinking the polygon by the stability margin
//! `d` moves every line inwards by `d` (`r -> r - d`); the shrunk polygon is what the ZMP
//! must stay in.
//!
//! Polygons are small (a support polygon has at most four feet; an intersection of two has
//! at most eight vertices), so [`ConvexPolygon`] keeps its vertices in a fixed array: it is
//! `Copy` and nothing here allocates.

use nalgebra::{Point2, Vector2};

/// Largest number of vertices a [`ConvexPolygon`] holds: the intersection of two
/// quadrilaterals.
pub const MAX_VERTICES: usize = 8;

/// Polygons with less area than this (m²) are treated as empty: a ZMP cannot be kept in a
/// point or a segment by a constraint sampled in time.
pub const MIN_AREA: f64 = 1e-10;

/// Vertices closer than this (m) are merged while clipping.
const MERGE_DISTANCE: f64 = 1e-12;

/// What can go wrong building a polygon.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PolygonError {
    #[error("expected 3 to {max} finite points, got {got} ({finite} finite)", max = MAX_VERTICES)]
    BadPointCount { got: usize, finite: usize },
    #[error("the points are collinear or coincide (hull area {area:.3e} m², less than {MIN_AREA:.0e} m²)")]
    Degenerate { area: f64 },
    #[error("an intersection of polygons with {left} and {right} vertices may exceed {MAX_VERTICES} vertices")]
    TooManyVertices { left: usize, right: usize },
}

/// A line `p x + q y + r = 0` of eq. (6), oriented so that `(p, q)` is the unit normal
/// pointing into its polygon: [`EdgeLine::value`] is positive inside and equals the distance
/// to the line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeLine {
    pub p: f64,
    pub q: f64,
    pub r: f64,
}

impl EdgeLine {
    /// The line through `from` and `to` with the inside on the left of `from -> to` (the
    /// edges of a counter-clockwise polygon). `from` and `to` must differ.
    pub fn through(from: Point2<f64>, to: Point2<f64>) -> Self {
        let direction = (to - from).normalize();
        // Left normal of the direction: inwards for a counter-clockwise polygon.
        let (p, q) = (-direction.y, direction.x);
        Self { p, q, r: -(p * from.x + q * from.y) }
    }

    /// `p x + q y + r`: the left side of eq. (6); the signed distance to the line.
    #[inline]
    pub fn value(&self, point: Point2<f64>) -> f64 {
        self.p * point.x + self.q * point.y + self.r
    }

    /// The same line moved inwards by `margin` (Fig. 5, right).
    pub fn shifted_inwards(&self, margin: f64) -> Self {
        Self { r: self.r - margin, ..*self }
    }
}

/// A convex polygon with positive area, vertices counter-clockwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConvexPolygon {
    vertices: [Point2<f64>; MAX_VERTICES],
    len: usize,
}

impl ConvexPolygon {
    /// The convex hull of `points` (Andrew's monotone chain): the support polygon of the
    /// stance feet. Points inside the hull or on its edges are dropped.
    pub fn hull(points: &[Point2<f64>]) -> Result<Self, PolygonError> {
        let finite = points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()).count();
        if points.len() < 3 || points.len() > MAX_VERTICES || finite != points.len() {
            return Err(PolygonError::BadPointCount { got: points.len(), finite });
        }
        let mut sorted = [Point2::origin(); MAX_VERTICES];
        sorted[..points.len()].copy_from_slice(points);
        let sorted = &mut sorted[..points.len()];
        sorted.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        let cross = |o: Point2<f64>, a: Point2<f64>, b: Point2<f64>| (a - o).perp(&(b - o));
        // Lower then upper chain; at most 2 n points on the stack.
        let mut hull = [Point2::origin(); 2 * MAX_VERTICES];
        let mut k = 0;
        for &p in sorted.iter() {
            while k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
                k -= 1;
            }
            hull[k] = p;
            k += 1;
        }
        let lower = k + 1;
        for &p in sorted.iter().rev().skip(1) {
            while k >= lower && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
                k -= 1;
            }
            hull[k] = p;
            k += 1;
        }
        // The last point repeats the first.
        let len = k.saturating_sub(1);
        let mut polygon = Self { vertices: [Point2::origin(); MAX_VERTICES], len };
        polygon.vertices[..len].copy_from_slice(&hull[..len]);
        let area = polygon.area();
        if len < 3 || area < MIN_AREA {
            return Err(PolygonError::Degenerate { area });
        }
        Ok(polygon)
    }

    /// The vertices, counter-clockwise.
    pub fn vertices(&self) -> &[Point2<f64>] {
        &self.vertices[..self.len]
    }

    /// The edge lines of eq. (6), one per edge, in vertex order.
    pub fn edges(&self) -> impl Iterator<Item = EdgeLine> + '_ {
        let v = self.vertices();
        (0..v.len()).map(move |i| EdgeLine::through(v[i], v[(i + 1) % v.len()]))
    }

    /// Area (shoelace formula).
    pub fn area(&self) -> f64 {
        let v = self.vertices();
        0.5 * (0..v.len()).map(|i| v[i].coords.perp(&v[(i + 1) % v.len()].coords)).sum::<f64>()
    }

    /// Mean of the vertices (a point inside).
    pub fn vertex_centroid(&self) -> Point2<f64> {
        let sum: Vector2<f64> = self.vertices().iter().map(|v| v.coords).sum();
        Point2::from(sum / self.len as f64)
    }

    /// The smallest left side of eq. (6) over the edges: the distance to the boundary for a
    /// point inside (positive), negative outside (then minus the largest violation of an
    /// edge line).
    pub fn margin(&self, point: Point2<f64>) -> f64 {
        self.edges().map(|e| e.value(point)).fold(f64::INFINITY, f64::min)
    }

    /// The polygon shrunk by the stability margin `d` (Winkler 2015, Fig. 5 right): every
    /// edge line moved inwards by `d`. For a convex polygon this is exactly the set of points
    /// whose distance to the outside is at least `d`. `None` if nothing (of positive area)
    /// is left.
    pub fn shrink(&self, margin: f64) -> Option<Self> {
        let mut shrunk = *self;
        for edge in self.edges() {
            shrunk = shrunk.clip(edge.shifted_inwards(margin))?;
        }
        Some(shrunk)
    }

    /// The intersection with `other` (clipping by its edge lines); `None` if it has no area:
    /// polygons that only touch count as disjoint.
    pub fn intersection(&self, other: &Self) -> Result<Option<Self>, PolygonError> {
        if self.len + other.len > MAX_VERTICES {
            return Err(PolygonError::TooManyVertices { left: self.len, right: other.len });
        }
        let mut clipped = *self;
        for edge in other.edges() {
            match clipped.clip(edge) {
                Some(c) => clipped = c,
                None => return Ok(None),
            }
        }
        Ok(Some(clipped))
    }

    /// Radius of the largest circle inside: the largest margin `shrink` accepts. Bisection on
    /// `shrink` (60 halvings, to machine precision); for diagnostics, not for hot paths.
    pub fn inscribed_radius(&self) -> f64 {
        // The margin of any inside point is a lower bound; half the area-equivalent width a
        // safe upper bound (a disc of radius r inside needs area pi r^2 <= area).
        let mut low = self.margin(self.vertex_centroid()).max(0.0);
        let mut high = (self.area() / std::f64::consts::PI).sqrt() * 1.000_001;
        for _ in 0..60 {
            let mid = 0.5 * (low + high);
            if self.shrink(mid).is_some() {
                low = mid;
            } else {
                high = mid;
            }
        }
        low
    }

    /// Sutherland-Hodgman: the part of the polygon on the inside of `line`. A convex polygon
    /// with `n` vertices gives at most `n + 1`.
    fn clip(&self, line: EdgeLine) -> Option<Self> {
        let v = self.vertices();
        let mut out = [Point2::origin(); MAX_VERTICES + 1];
        let mut k = 0;
        let push = |p: Point2<f64>, out: &mut [Point2<f64>; MAX_VERTICES + 1], k: &mut usize| {
            if *k > 0 && (out[*k - 1] - p).norm() <= MERGE_DISTANCE {
                return;
            }
            out[*k] = p;
            *k += 1;
        };
        for i in 0..v.len() {
            let (a, b) = (v[i], v[(i + 1) % v.len()]);
            let (va, vb) = (line.value(a), line.value(b));
            if va >= 0.0 {
                push(a, &mut out, &mut k);
            }
            if (va >= 0.0) != (vb >= 0.0) {
                push(a + (b - a) * (va / (va - vb)), &mut out, &mut k);
            }
        }
        while k > 1 && (out[k - 1] - out[0]).norm() <= MERGE_DISTANCE {
            k -= 1;
        }
        if !(3..=MAX_VERTICES).contains(&k) {
            // k > MAX_VERTICES cannot happen for inputs of at most MAX_VERTICES - 1 vertices;
            // `intersection` checks its inputs so that it never does.
            return None;
        }
        let mut polygon = Self { vertices: [Point2::origin(); MAX_VERTICES], len: k };
        polygon.vertices[..k].copy_from_slice(&out[..k]);
        (polygon.area() >= MIN_AREA).then_some(polygon)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Point2<f64> {
        Point2::new(x, y)
    }

    #[test]
    fn hull_orders_counter_clockwise_and_drops_inner_points() {
        let hull = ConvexPolygon::hull(&[p(1.0, 1.0), p(0.0, 0.0), p(0.5, 0.5), p(1.0, 0.0), p(0.0, 1.0)]).unwrap();
        assert_eq!(hull.vertices(), &[p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
        assert!((hull.area() - 1.0).abs() < 1e-15);
        // Inward normals: the centre is at distance 0.5 from every edge.
        for e in hull.edges() {
            assert!((e.value(p(0.5, 0.5)) - 0.5).abs() < 1e-15, "{e:?}");
            assert!((e.p.hypot(e.q) - 1.0).abs() < 1e-15);
        }
        assert!((hull.margin(p(0.5, 0.2)) - 0.2).abs() < 1e-15);
        assert!((hull.margin(p(1.3, 0.5)) + 0.3).abs() < 1e-15);
    }

    #[test]
    fn hull_rejects_degenerate_and_bad_input() {
        assert!(matches!(
            ConvexPolygon::hull(&[p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0)]),
            Err(PolygonError::Degenerate { .. })
        ));
        assert!(matches!(ConvexPolygon::hull(&[p(0.0, 0.0), p(1.0, 1.0)]), Err(PolygonError::BadPointCount { .. })));
        let e = ConvexPolygon::hull(&[p(0.0, 0.0), p(1.0, f64::NAN), p(0.0, 1.0)]).unwrap_err();
        assert_eq!(e, PolygonError::BadPointCount { got: 3, finite: 2 });
    }

    /// Shrinking a triangle by d gives the triangle with the same incentre, scaled by
    /// (r - d) / r (r the inradius 2 A / perimeter).
    #[test]
    fn shrunk_triangle_is_the_scaled_triangle_about_the_incentre() {
        let (a, b, c) = (p(0.37, 0.33), p(0.37, -0.33), p(-0.37, 0.33));
        let triangle = ConvexPolygon::hull(&[a, b, c]).unwrap();
        let (la, lb, lc) = ((b - c).norm(), (c - a).norm(), (a - b).norm());
        let perimeter = la + lb + lc;
        let inradius = 2.0 * triangle.area() / perimeter;
        let incentre = Point2::from((a.coords * la + b.coords * lb + c.coords * lc) / perimeter);
        let d = 0.06;
        let shrunk = triangle.shrink(d).unwrap();
        assert_eq!(shrunk.vertices().len(), 3);
        let scale = (inradius - d) / inradius;
        for v in [a, b, c] {
            let expected = incentre + (v - incentre) * scale;
            assert!(shrunk.vertices().iter().any(|s| (s - expected).norm() < 1e-14), "{expected} not in {shrunk:?}");
        }
        // Every shrunk edge is the original one moved in by d.
        for (e, s) in triangle.edges().zip(shrunk.edges()) {
            assert!((e.r - d - s.r).abs() < 1e-14 && (e.p - s.p).abs() < 1e-14 && (e.q - s.q).abs() < 1e-14);
        }
        // `shrink` calls a polygon of less than MIN_AREA empty: the shrunk triangle's area is
        // A ((r - d) / r)^2, so the bisection stops short of r by r (MIN_AREA / A)^(1/2).
        let short = inradius * (MIN_AREA / triangle.area()).sqrt();
        let bisected = triangle.inscribed_radius();
        assert!(bisected <= inradius && inradius - bisected < 1.01 * short, "{bisected} vs {inradius}");
        assert!(triangle.shrink(inradius * 0.999).is_some());
        assert!(triangle.shrink(inradius * 1.001).is_none());
    }

    #[test]
    fn rectangle_inscribed_radius_and_shrink() {
        let rect = ConvexPolygon::hull(&[p(0.0, 0.0), p(2.0, 0.0), p(2.0, 0.5), p(0.0, 0.5)]).unwrap();
        assert!((rect.inscribed_radius() - 0.25).abs() < 1e-12);
        let shrunk = rect.shrink(0.1).unwrap();
        assert!((shrunk.area() - 1.8 * 0.3).abs() < 1e-14);
    }

    #[test]
    fn intersection_of_overlapping_and_touching_polygons() {
        let a = ConvexPolygon::hull(&[p(0.0, 0.0), p(2.0, 0.0), p(0.0, 2.0)]).unwrap();
        let b = ConvexPolygon::hull(&[p(0.0, 0.0), p(2.0, 0.0), p(2.0, 2.0)]).unwrap();
        // Two halves of a square cut along different diagonals: the lower quarter triangle.
        let i = a.intersection(&b).unwrap().unwrap();
        assert!((i.area() - 1.0).abs() < 1e-14, "{i:?}");
        // Halves of the square cut along the same diagonal only touch.
        let c = ConvexPolygon::hull(&[p(2.0, 0.0), p(2.0, 2.0), p(0.0, 2.0)]).unwrap();
        assert_eq!(a.intersection(&c).unwrap(), None);
        let far = ConvexPolygon::hull(&[p(5.0, 5.0), p(6.0, 5.0), p(5.0, 6.0)]).unwrap();
        assert_eq!(a.intersection(&far).unwrap(), None);
    }
}
