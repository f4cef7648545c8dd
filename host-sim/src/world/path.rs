//! The reference path: a polyline of waypoints in the world frame, open or a closed loop, with
//! arc-length parametrisation, projection and look-ahead.
//!
//! Points are nalgebra's `Point2<f64>`, segments `Vector2<f64>`.
//!
//! ```
//! use host_sim::world::path::RefPath;
//! use nalgebra::Point2;
//! let corners = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
//! let square = RefPath::new(corners.map(|(x, y)| Point2::new(x, y)).to_vec(), true).unwrap();
//! assert_eq!(square.length(), 16.0);
//! let (p, heading) = square.point_at(5.0);
//! assert_eq!(p, Point2::new(4.0, 1.0));
//! assert!((heading - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
//! ```

use nalgebra::Point2;

/// A polyline path with cumulative arc lengths.
#[derive(Clone, Debug, PartialEq)]
pub struct RefPath {
    points: Vec<Point2<f64>>,
    /// Arc length at the start of each segment, and the total at the end.
    cumulative: Vec<f64>,
    headings: Vec<f64>,
    closed: bool,
}

/// Why a path was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum PathError {
    /// Fewer than two waypoints (three for a loop).
    TooFew,
    /// Waypoint `i` is not finite.
    NotFinite(usize),
    /// Waypoint `i` coincides with the one before it.
    Repeated(usize),
}

impl std::fmt::Display for PathError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathError::TooFew => write!(f, "needs at least 2 waypoints (3 for a closed loop)"),
            PathError::NotFinite(i) => write!(f, "waypoint {i} is not finite"),
            PathError::Repeated(i) => {
                write!(f, "waypoint {i} is within 1 mm of the waypoint before it")
            }
        }
    }
}

impl RefPath {
    /// A path through `points`; `closed` joins the last point back to the first.
    pub fn new(points: Vec<Point2<f64>>, closed: bool) -> Result<Self, PathError> {
        if points.len() < 2 || closed && points.len() < 3 {
            return Err(PathError::TooFew);
        }
        for (i, p) in points.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(PathError::NotFinite(i));
            }
        }
        let n = points.len();
        let segs = if closed { n } else { n - 1 };
        let mut cumulative = Vec::with_capacity(segs + 1);
        let mut headings = Vec::with_capacity(segs);
        let mut s = 0.0;
        for i in 0..segs {
            let d = points[(i + 1) % n] - points[i];
            let len = d.norm();
            if len < 1e-3 {
                return Err(PathError::Repeated((i + 1) % n));
            }
            cumulative.push(s);
            headings.push(libm::atan2(d.y, d.x));
            s += len;
        }
        cumulative.push(s);
        Ok(Self {
            points,
            cumulative,
            headings,
            closed,
        })
    }

    /// Total length (m), the closing segment included for a loop.
    pub fn length(&self) -> f64 {
        self.cumulative[self.cumulative.len() - 1]
    }

    /// Whether the path is a closed loop.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The waypoints.
    pub fn points(&self) -> &[Point2<f64>] {
        &self.points
    }

    fn segment_count(&self) -> usize {
        self.headings.len()
    }

    fn segment(&self, i: usize) -> (Point2<f64>, Point2<f64>) {
        let n = self.points.len();
        (self.points[i], self.points[(i + 1) % n])
    }

    /// Arc length wrapped onto the path: modulo the length for a loop, clamped for an open path.
    pub fn wrap(&self, s: f64) -> f64 {
        let l = self.length();
        if self.closed {
            let w = s - l * libm::floor(s / l);
            if w >= l { 0.0 } else { w }
        } else {
            s.clamp(0.0, l)
        }
    }

    fn segment_at(&self, s: f64) -> usize {
        // Last segment whose start is <= s.
        match self.cumulative[..self.segment_count()]
            .binary_search_by(|c| c.partial_cmp(&s).unwrap_or(std::cmp::Ordering::Less))
        {
            Ok(i) => i,
            Err(i) => i.saturating_sub(1),
        }
    }

    /// The point at arc length `s` (wrapped) and the path's heading there.
    pub fn point_at(&self, s: f64) -> (Point2<f64>, f64) {
        let s = self.wrap(s);
        let i = self.segment_at(s);
        let (a, b) = self.segment(i);
        let len = self.cumulative[i + 1] - self.cumulative[i];
        let t = ((s - self.cumulative[i]) / len).clamp(0.0, 1.0);
        (a + (b - a) * t, self.headings[i])
    }

    fn project_on(&self, i: usize, p: &Point2<f64>) -> (f64, f64) {
        let (a, b) = self.segment(i);
        let d = b - a;
        let t = ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        let d2 = (p - (a + d * t)).norm_squared();
        (
            self.cumulative[i] + t * (self.cumulative[i + 1] - self.cumulative[i]),
            d2,
        )
    }

    /// The arc length of the point of the path nearest to `p`, and the distance to it.
    /// Ties go to the lowest arc length.
    pub fn project(&self, p: &Point2<f64>) -> (f64, f64) {
        let mut best = (0.0, f64::INFINITY);
        for i in 0..self.segment_count() {
            let (s, d2) = self.project_on(i, p);
            if d2 < best.1 {
                best = (s, d2);
            }
        }
        (best.0, libm::sqrt(best.1))
    }

    /// Like [`RefPath::project`], but only onto the part of the path between `s − behind` and
    /// `s + ahead` (wrapped on a loop): the projection cannot jump to a neighbouring hallway.
    pub fn project_near(&self, p: &Point2<f64>, s: f64, behind: f64, ahead: f64) -> (f64, f64) {
        let l = self.length();
        let mut best = (self.wrap(s), f64::INFINITY);
        for i in 0..self.segment_count() {
            let (a, b) = (self.cumulative[i], self.cumulative[i + 1]);
            // Does [a, b] intersect [s - behind, s + ahead] (modulo l on a loop)?
            let hit = if self.closed {
                [-l, 0.0, l]
                    .iter()
                    .any(|o| a + o <= s + ahead && b + o >= s - behind)
            } else {
                a <= s + ahead && b >= s - behind
            };
            if !hit {
                continue;
            }
            let (ps, d2) = self.project_on(i, p);
            if d2 < best.1 {
                best = (ps, d2);
            }
        }
        (best.0, libm::sqrt(best.1))
    }

    /// Signed difference `b − a` of two arc lengths, the short way round on a loop.
    pub fn delta(&self, a: f64, b: f64) -> f64 {
        let d = b - a;
        if self.closed {
            let l = self.length();
            if d > l / 2.0 {
                d - l
            } else if d < -l / 2.0 {
                d + l
            } else {
                d
            }
        } else {
            d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(v: &[(f64, f64)]) -> Vec<Point2<f64>> {
        v.iter().map(|&(x, y)| Point2::new(x, y)).collect()
    }

    #[test]
    fn projection_and_wrap() {
        let p = RefPath::new(pts(&[(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]), true).unwrap();
        let (s, d) = p.project(&Point2::new(2.0, -0.5));
        assert_eq!((s, d), (2.0, 0.5));
        let (s, _) = p.project(&Point2::new(-0.5, 2.0));
        assert_eq!(s, 14.0);
        assert_eq!(p.wrap(17.0), 1.0);
        assert_eq!(p.wrap(-1.0), 15.0);
        assert_eq!(p.delta(15.5, 0.5), 1.0);
        assert_eq!(p.delta(0.5, 15.5), -1.0);
        // Near-projection stays on the segments of the window even when another part is nearer.
        assert_eq!(p.project(&Point2::new(3.9, 2.0)).0, 6.0);
        let (s, d) = p.project_near(&Point2::new(3.9, 2.0), 1.0, 1.0, 2.0);
        assert_eq!((s, d), (3.9, 2.0));
        let (q, h) = p.point_at(15.0);
        assert_eq!(q, Point2::new(0.0, 1.0));
        assert!((h + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn bad_paths_are_refused() {
        assert_eq!(
            RefPath::new(pts(&[(0.0, 0.0)]), false),
            Err(PathError::TooFew)
        );
        assert_eq!(
            RefPath::new(pts(&[(0.0, 0.0), (1.0, 0.0)]), true),
            Err(PathError::TooFew)
        );
        assert_eq!(
            RefPath::new(pts(&[(0.0, 0.0), (0.0, 0.0)]), false),
            Err(PathError::Repeated(1))
        );
        assert_eq!(
            RefPath::new(pts(&[(0.0, f64::NAN), (0.0, 1.0)]), false),
            Err(PathError::NotFinite(0))
        );
        let open = RefPath::new(pts(&[(0.0, 0.0), (1.0, 0.0)]), false).unwrap();
        assert_eq!(open.wrap(3.0), 1.0);
        assert_eq!(open.point_at(3.0).0.x, 1.0);
    }
}
