//! Plane geometry: the world frame's [`Point`], latitude and longitude ([`LatLon`]), polygon and
//! segment tests, routes around no-go areas and the no-go list a mission passes to the
//! navigation modules. `world` and the planner build on it; it depends on nothing of theirs.
//!
//! A route is the shortest path through a visibility graph: its corners are the corners of the
//! no-go polygons, pushed out by a clearance, and two corners are joined when the segment
//! between them keeps the clearance from every polygon. The graphs of a plan are small (tens of
//! corners), so the quadratic construction costs microseconds.

use std::collections::BinaryHeap;
use std::fmt;

/// Mean Earth radius, for the local latitude/longitude conversion (the world files' too).
const EARTH_RADIUS_M: f64 = 6_371_008.8;

/// A point of the world frame, in metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Point {
    pub x: f64,
    pub y: f64,
}

impl Point {
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    pub(crate) fn sub(self, other: Point) -> Point {
        Point::new(self.x - other.x, self.y - other.y)
    }

    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }

    pub fn distance(self, other: Point) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }
}

impl fmt::Display for Point {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {})", round_mm(self.x), round_mm(self.y))
    }
}

/// A latitude and longitude in degrees (WGS 84).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatLon {
    pub lat_deg: f64,
    pub lon_deg: f64,
}

impl LatLon {
    pub const fn new(lat_deg: f64, lon_deg: f64) -> Self {
        Self { lat_deg, lon_deg }
    }

    /// The point of the local frame whose (0, 0) is `origin` (x east, y north, metres; a local
    /// equirectangular projection, accurate to centimetres over a few kilometres).
    pub fn to_local(self, origin: LatLon) -> Point {
        Point::new(
            (self.lon_deg - origin.lon_deg).to_radians()
                * EARTH_RADIUS_M
                * origin.lat_deg.to_radians().cos(),
            (self.lat_deg - origin.lat_deg).to_radians() * EARTH_RADIUS_M,
        )
    }

    /// The great-circle distance to `other` in metres (haversine, on a sphere of the Earth's
    /// mean radius): what [`LatLon::to_local`]'s flat frame is measured against.
    pub fn great_circle_m(self, other: LatLon) -> f64 {
        let (lat1, lat2) = (self.lat_deg.to_radians(), other.lat_deg.to_radians());
        let half_dlat = (lat2 - lat1) / 2.0;
        let half_dlon = (other.lon_deg - self.lon_deg).to_radians() / 2.0;
        let h = half_dlat.sin().powi(2) + lat1.cos() * lat2.cos() * half_dlon.sin().powi(2);
        2.0 * EARTH_RADIUS_M * h.sqrt().min(1.0).asin()
    }

    /// The inverse of [`LatLon::to_local`].
    pub fn from_local(p: Point, origin: LatLon) -> LatLon {
        LatLon::new(
            origin.lat_deg + (p.y / EARTH_RADIUS_M).to_degrees(),
            origin.lon_deg
                + (p.x / (EARTH_RADIUS_M * origin.lat_deg.to_radians().cos())).to_degrees(),
        )
    }
}

/// Corners further than this from a polygon edge are pushed out along the bisector only up to
/// this many clearances, so that a sharp spike does not send the route far away.
const MAX_MITER: f64 = 3.0;

/// The area a robot must keep out of: a closed polygon (the first corner is not repeated).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Polygon {
    pub corners: Vec<Point>,
}

impl Polygon {
    pub fn new(corners: Vec<Point>) -> Self {
        let mut corners = corners;
        if corners.len() > 1 && corners.first() == corners.last() {
            corners.pop();
        }
        Self { corners }
    }

    pub fn edges(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        let n = self.corners.len();
        (0..n).map(move |i| (self.corners[i], self.corners[(i + 1) % n]))
    }

    /// Even-odd rule: whether `p` is inside the outline.
    pub fn contains(&self, p: Point) -> bool {
        inside(self.edges(), p)
    }

    /// Twice the signed area: positive when the corners turn counter-clockwise.
    fn signed_area2(&self) -> f64 {
        self.edges().map(|(a, b)| a.x * b.y - b.x * a.y).sum()
    }

    /// The area it encloses, whichever way its corners turn.
    pub fn area(&self) -> f64 {
        self.signed_area2().abs() / 2.0
    }

    /// The centre of what it encloses (its centroid); the mean of its corners when it encloses
    /// nothing.
    pub fn centroid(&self) -> Point {
        let Some(&o) = self.corners.first() else {
            return Point::new(0.0, 0.0);
        };
        // Measured from the first corner, so that far from the origin nothing is lost.
        let (mut x, mut y, mut twice) = (0.0, 0.0, 0.0);
        for (a, b) in self.edges() {
            let (ax, ay, bx, by) = (a.x - o.x, a.y - o.y, b.x - o.x, b.y - o.y);
            let cross = ax * by - bx * ay;
            twice += cross;
            x += (ax + bx) * cross;
            y += (ay + by) * cross;
        }
        if twice.abs() < f64::EPSILON {
            let n = self.corners.len() as f64;
            let (x, y) = self
                .corners
                .iter()
                .fold((0.0, 0.0), |(x, y), p| (x + p.x, y + p.y));
            return Point::new(x / n, y / n);
        }
        Point::new(o.x + x / (3.0 * twice), o.y + y / (3.0 * twice))
    }

    /// Whether two of its edges cross (a polygon must not, to have an inside).
    pub fn crosses_itself(&self) -> bool {
        let edges: Vec<(Point, Point)> = self.edges().collect();
        let n = edges.len();
        for i in 0..n {
            for j in i + 1..n {
                // Neighbouring edges share a corner; that is not a crossing.
                if j == i + 1 || (i == 0 && j == n - 1) {
                    continue;
                }
                if segments_cross(edges[i].0, edges[i].1, edges[j].0, edges[j].1) {
                    return true;
                }
            }
        }
        false
    }

    /// The distance from `p` to the outline (0 on it), whether `p` is inside or not.
    pub fn distance_to_outline(&self, p: Point) -> f64 {
        self.edges()
            .map(|(a, b)| segment_distance(p, a, b))
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether any point of the polygon lies within `margin` of the box around `a` and `b`
    /// (a cheap test that rules out most far-away polygons).
    pub fn near_box(&self, a: Point, b: Point, margin: f64) -> bool {
        let (min_x, max_x) = (a.x.min(b.x) - margin, a.x.max(b.x) + margin);
        let (min_y, max_y) = (a.y.min(b.y) - margin, a.y.max(b.y) + margin);
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in &self.corners {
            lo_x = lo_x.min(p.x);
            hi_x = hi_x.max(p.x);
            lo_y = lo_y.min(p.y);
            hi_y = hi_y.max(p.y);
        }
        lo_x <= max_x && hi_x >= min_x && lo_y <= max_y && hi_y >= min_y
    }

    /// Whether the segment `a`–`b` comes closer than `clearance` to the polygon or enters it.
    pub fn blocks(&self, a: Point, b: Point, clearance: f64) -> bool {
        if !self.near_box(a, b, clearance) {
            return false;
        }
        if self.contains(a) || self.contains(b) {
            return true;
        }
        self.edges().any(|(c, d)| {
            segments_cross(a, b, c, d)
                || segment_distance(c, a, b) < clearance
                || segment_distance(d, a, b) < clearance
                || segment_distance(a, c, d) < clearance
                || segment_distance(b, c, d) < clearance
        })
    }

    /// The corners pushed outwards by `margin` along their bisectors (a miter, capped).
    pub fn inflated_corners(&self, margin: f64) -> Vec<Point> {
        let n = self.corners.len();
        let orientation = if self.signed_area2() >= 0.0 {
            1.0
        } else {
            -1.0
        };
        (0..n)
            .map(|i| {
                let prev = self.corners[(i + n - 1) % n];
                let here = self.corners[i];
                let next = self.corners[(i + 1) % n];
                // Outward normals of the two edges meeting here.
                let n1 = outward_normal(prev, here, orientation);
                let n2 = outward_normal(here, next, orientation);
                let sum = Point::new(n1.x + n2.x, n1.y + n2.y);
                let len = sum.x.hypot(sum.y);
                if len < 1e-9 {
                    return Point::new(here.x + n1.x * margin, here.y + n1.y * margin);
                }
                let bisector = Point::new(sum.x / len, sum.y / len);
                let cos_half = bisector.x * n1.x + bisector.y * n1.y;
                let reach = (margin / cos_half.max(1e-9)).min(margin * MAX_MITER);
                Point::new(here.x + bisector.x * reach, here.y + bisector.y * reach)
            })
            .collect()
    }
}

/// Even-odd rule: whether `p` is inside the outline made of `edges`.
pub fn inside(edges: impl Iterator<Item = (Point, Point)>, p: Point) -> bool {
    let mut inside = false;
    for (a, b) in edges {
        if (a.y > p.y) != (b.y > p.y) {
            let x_cross = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if p.x < x_cross {
                inside = !inside;
            }
        }
    }
    inside
}

fn outward_normal(a: Point, b: Point, orientation: f64) -> Point {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let len = dx.hypot(dy).max(1e-12);
    // For a counter-clockwise polygon the outside is on the right of each edge.
    Point::new(orientation * dy / len, -orientation * dx / len)
}

fn cross(o: Point, a: Point, b: Point) -> f64 {
    (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
}

/// Whether segments `a`–`b` and `c`–`d` cross at a point inside both (touching ends count).
pub fn segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool {
    let d1 = cross(c, d, a);
    let d2 = cross(c, d, b);
    let d3 = cross(a, b, c);
    let d4 = cross(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: Point, q: Point, r: Point| segment_distance(r, p, q) < 1e-12;
    (d1 == 0.0 && on(c, d, a))
        || (d2 == 0.0 && on(c, d, b))
        || (d3 == 0.0 && on(a, b, c))
        || (d4 == 0.0 && on(a, b, d))
}

/// The distance from `p` to the segment `a`–`b`.
pub fn segment_distance(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.x - a.x) * dx + (p.y - a.y) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.x - (a.x + t * dx)).hypot(p.y - (a.y + t * dy))
}

pub fn distance(a: Point, b: Point) -> f64 {
    (a.x - b.x).hypot(a.y - b.y)
}

/// The length of a path through `points` in order.
pub fn path_length(points: &[Point]) -> f64 {
    points.windows(2).map(|w| distance(w[0], w[1])).sum()
}

/// The shortest path from `from` to `to` that keeps `clearance` from every polygon: the corners
/// to drive through, ending with `to` (without `from`); `None` when there is none. Polygons that
/// contain `from` are ignored, so that a robot which strayed inside one can still get out, and
/// `to` is expected outside every polygon.
///
/// When the straight line is clear of the polygons it is the route, whatever else is in the
/// way (the robot's own obstacle avoidance deals with walls). A detour may also turn at
/// `extra_corners` (around the world's obstacles) and must pass `detour_ok` on each of its
/// segments (a check against the world's walls).
pub fn route(
    from: Point,
    to: Point,
    no_go: &[Polygon],
    clearance: f64,
    extra_corners: &[Point],
    detour_ok: &dyn Fn(Point, Point) -> bool,
) -> Option<Vec<Point>> {
    let active: Vec<&Polygon> = no_go
        .iter()
        .filter(|polygon| polygon.corners.len() >= 3 && !polygon.contains(from))
        .collect();
    if active
        .iter()
        .all(|polygon| !polygon.blocks(from, to, clearance))
    {
        return Some(vec![to]);
    }
    // Corners sit a little further out than the clearance that segments are checked against,
    // so that a segment from one corner to the next along an edge is not refused.
    let mut nodes = vec![from, to];
    nodes.extend(extra_corners.iter().copied().filter(|corner| {
        active.iter().all(|polygon| {
            !polygon.contains(*corner) && polygon.distance_to_outline(*corner) >= clearance
        })
    }));
    for polygon in &active {
        nodes.extend(
            polygon
                .inflated_corners(clearance * 1.05 + 0.01)
                .into_iter()
                .filter(|corner| {
                    active.iter().all(|other| {
                        !other.contains(*corner) && other.distance_to_outline(*corner) >= clearance
                    })
                }),
        );
    }
    let free = |a: Point, b: Point| {
        active
            .iter()
            .all(|polygon| !polygon.blocks(a, b, clearance))
            && detour_ok(a, b)
    };
    // Dijkstra on the complete visibility graph, edges checked as they are relaxed.
    let n = nodes.len();
    let mut best = vec![f64::INFINITY; n];
    let mut previous = vec![usize::MAX; n];
    let mut done = vec![false; n];
    let mut queue = BinaryHeap::new();
    best[0] = 0.0;
    queue.push(Entry { cost: 0.0, node: 0 });
    while let Some(Entry { cost, node }) = queue.pop() {
        if done[node] {
            continue;
        }
        done[node] = true;
        if node == 1 {
            break;
        }
        for next in 1..n {
            if done[next] || !free(nodes[node], nodes[next]) {
                continue;
            }
            let through = cost + distance(nodes[node], nodes[next]);
            if through < best[next] {
                best[next] = through;
                previous[next] = node;
                queue.push(Entry {
                    cost: through,
                    node: next,
                });
            }
        }
    }
    if !best[1].is_finite() {
        return None;
    }
    let mut path = Vec::new();
    let mut node = 1;
    while node != 0 {
        path.push(nodes[node]);
        node = previous[node];
    }
    path.reverse();
    Some(path)
}

/// A queue entry of the shortest-path search: the smallest cost comes out first.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    cost: f64,
    node: usize,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other.cost.total_cmp(&self.cost)
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Writes polygons the way [`parse_polygons`] reads them: `x,y x,y x,y; x,y …` in metres.
pub fn format_polygons(polygons: &[Polygon]) -> String {
    polygons
        .iter()
        .map(|polygon| {
            polygon
                .corners
                .iter()
                .map(|p| format!("{},{}", round_mm(p.x), round_mm(p.y)))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// `is 0.25 m from`, or `is on` when the distance rounds to 0 mm (a point in a wall, or in an
/// occupied cell of a map, is not "0 m from" it).
pub fn is_from(distance_m: f64) -> String {
    match round_mm(distance_m).as_str() {
        "0" => "is on".to_owned(),
        text => format!("is {text} m from"),
    }
}

/// A coordinate written to the millimetre, without trailing zeros (`-0` is `0`).
pub fn round_mm(value: f64) -> String {
    let mut text = String::new();
    push_mm(&mut text, value);
    text
}

/// Appends [`round_mm`]'s text of `value` to `out`, without a string of its own: a compiled
/// plan writes tens of thousands of coordinates.
pub fn push_mm(out: &mut String, value: f64) {
    let scaled = value * 1000.0;
    let nearest = scaled.round();
    // Below 2^40 mm the product is within 2^-12 of the exact one, so when it is this far from a
    // tie the nearest whole millimetre is the decimal rounding the formatter makes; at a tie,
    // beyond, or for what is not a number, the formatter decides.
    if nearest.abs() < 1e12 && (scaled - nearest).abs() < 0.499 {
        let mm = nearest as i64;
        if mm < 0 {
            out.push('-');
        }
        let mm = mm.unsigned_abs();
        let (whole, fraction) = (mm / 1000, mm % 1000);
        push_digits(out, whole);
        if fraction != 0 {
            out.push('.');
            let digits = [fraction / 100, fraction / 10 % 10, fraction % 10];
            let used = if fraction % 100 == 0 {
                1
            } else if fraction % 10 == 0 {
                2
            } else {
                3
            };
            for digit in &digits[..used] {
                out.push(char::from(b'0' + *digit as u8));
            }
        }
        return;
    }
    out.push_str(&trimmed_decimal(value, 3));
}

/// `value` with `places` decimals, rounded as the formatter rounds, without trailing zeros
/// (`-0` is `0`).
pub fn trimmed_decimal(value: f64, places: usize) -> String {
    let text = format!("{value:.places$}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_owned()
    } else {
        text.to_owned()
    }
}

fn push_digits(out: &mut String, value: u64) {
    let mut digits = [0u8; 20];
    let mut at = digits.len();
    let mut rest = value;
    loop {
        at -= 1;
        digits[at] = b'0' + (rest % 10) as u8;
        rest /= 10;
        if rest == 0 {
            break;
        }
    }
    for digit in &digits[at..] {
        out.push(char::from(*digit));
    }
}

/// Reads `x,y x,y x,y; x,y …`: polygons of three corners or more, separated by `;`. An empty
/// text is no polygon.
pub fn parse_polygons(text: &str) -> Result<Vec<Polygon>, String> {
    let mut polygons = Vec::new();
    for (index, part) in text.split(';').enumerate() {
        if part.trim().is_empty() {
            continue;
        }
        let mut corners = Vec::new();
        for pair in part.split_whitespace() {
            let parsed = pair
                .split_once(',')
                .and_then(|(x, y)| Some(Point::new(x.parse().ok()?, y.parse().ok()?)))
                .filter(|p| p.x.is_finite() && p.y.is_finite());
            match parsed {
                Some(p) => corners.push(p),
                None => {
                    return Err(format!(
                        "polygon {}: `{pair}` is not a corner `X,Y` in metres",
                        index + 1
                    ));
                }
            }
        }
        let polygon = Polygon::new(corners);
        if polygon.corners.len() < 3 {
            return Err(format!(
                "polygon {} has {} corners; it needs 3 or more",
                index + 1,
                polygon.corners.len()
            ));
        }
        polygons.push(polygon);
    }
    Ok(polygons)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::random::SplitMix64;

    #[test]
    fn millimetres_are_written_as_the_formatter_rounds_them() {
        let mut rng = SplitMix64(7);
        let mut values = vec![
            0.0,
            -0.0,
            0.0004,
            -0.0004,
            0.0005,
            -0.0005,
            0.0015,
            2.675,
            1.0005,
            1e9,
            -1e9,
            1e13,
            123.4,
            -0.1,
            0.25,
            7.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
        ];
        for _ in 0..200_000 {
            let magnitude = 10f64.powi((rng.next_u64() % 14) as i32 - 4);
            values.push(rng.uniform(-magnitude, magnitude));
            // Ties and near-ties of the millimetre, where the product's rounding could differ.
            let mm = rng.uniform(-1e7, 1e7).round();
            values.push((mm + 0.5) / 1000.0);
            values.push((mm + 0.4995) / 1000.0);
        }
        for value in values {
            assert_eq!(round_mm(value), trimmed_decimal(value, 3), "{value:e}");
        }
    }

    const ANY: fn(Point, Point) -> bool = |_, _| true;

    fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> Polygon {
        Polygon::new(vec![
            Point::new(x0, y0),
            Point::new(x1, y0),
            Point::new(x1, y1),
            Point::new(x0, y1),
        ])
    }

    #[test]
    fn a_clear_line_is_the_route() {
        let route = route(
            Point::new(0.0, 0.0),
            Point::new(10.0, 0.0),
            &[],
            1.0,
            &[],
            &ANY,
        );
        assert_eq!(route, Some(vec![Point::new(10.0, 0.0)]));
    }

    #[test]
    fn routes_go_around_with_clearance_and_stay_short() {
        let block = square(4.0, -2.0, 6.0, 3.0);
        let from = Point::new(0.0, 0.0);
        let to = Point::new(10.0, 0.0);
        let path =
            route(from, to, std::slice::from_ref(&block), 1.0, &[], &ANY).expect("a way around");
        assert_eq!(path.last(), Some(&to));
        let mut all = vec![from];
        all.extend(&path);
        for pair in all.windows(2) {
            assert!(
                !block.blocks(pair[0], pair[1], 0.99),
                "{pair:?} cuts the block"
            );
        }
        // Around the south side: down to y = -3, a little over 10 m straight.
        let length = path_length(&all);
        assert!(length > 10.5 && length < 13.0, "{length}");
        assert!(all.iter().all(|p| p.y < 0.1), "{all:?}");
    }

    #[test]
    fn detours_respect_the_extra_check() {
        let block = square(4.0, -2.0, 6.0, 3.0);
        // A wall south of the block: the way round must go north.
        let north_only = |a: Point, b: Point| a.y > -1.0 && b.y > -1.0;
        let path = route(
            Point::new(0.0, 0.0),
            Point::new(10.0, 0.0),
            std::slice::from_ref(&block),
            1.0,
            &[],
            &north_only,
        )
        .expect("round the north");
        assert!(path.iter().any(|p| p.y > 3.0), "{path:?}");
    }

    #[test]
    fn no_route_through_a_closed_fence() {
        // A ring of four blocks around the goal leaves no gap wider than twice the clearance.
        let fence = [
            square(-5.0, -5.0, 5.0, -4.0),
            square(-5.0, 4.0, 5.0, 5.0),
            square(-5.0, -5.0, -4.0, 5.0),
            square(4.0, -5.0, 5.0, 5.0),
        ];
        assert_eq!(
            route(
                Point::new(20.0, 0.0),
                Point::new(0.0, 0.0),
                &fence,
                0.5,
                &[],
                &ANY
            ),
            None
        );
    }

    #[test]
    fn a_robot_inside_an_area_may_leave_it() {
        let area = square(0.0, 0.0, 4.0, 4.0);
        let path = route(
            Point::new(1.0, 1.0),
            Point::new(10.0, 1.0),
            &[area],
            1.0,
            &[],
            &ANY,
        );
        assert_eq!(path, Some(vec![Point::new(10.0, 1.0)]));
    }

    #[test]
    fn self_crossing_outlines() {
        assert!(!square(0.0, 0.0, 1.0, 1.0).crosses_itself());
        let bow_tie = Polygon::new(vec![
            Point::new(0.0, 0.0),
            Point::new(1.0, 1.0),
            Point::new(1.0, 0.0),
            Point::new(0.0, 1.0),
        ]);
        assert!(bow_tie.crosses_itself());
    }

    #[test]
    fn polygon_text_round_trip_and_errors() {
        let polygons = vec![square(0.0, 0.0, 1.5, 2.0), square(-3.25, 1.0, 0.0, 4.0)];
        let text = format_polygons(&polygons);
        assert_eq!(text, "0,0 1.5,0 1.5,2 0,2; -3.25,1 0,1 0,4 -3.25,4");
        assert_eq!(parse_polygons(&text), Ok(polygons));
        assert_eq!(parse_polygons(""), Ok(vec![]));
        assert_eq!(
            parse_polygons("0,0 1,0; 2,2 3,3 x,1"),
            Err("polygon 1 has 2 corners; it needs 3 or more".into())
        );
        assert_eq!(
            parse_polygons("0,0 1,0 1,1; 2,2 3,3 x,1"),
            Err("polygon 2: `x,1` is not a corner `X,Y` in metres".into())
        );
        assert!(parse_polygons("0,0 1,0 NaN,1").is_err());
    }
}
