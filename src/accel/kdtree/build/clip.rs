//! Perfect splits: the bounds of the part of a primitive inside a cell.
//!
//! A straddling triangle is clipped (Sutherland-Hodgman) to the node's cell, only by the
//! faces that cut its bounds, and that polygon is cut by the split plane for each child,
//! so its bounds are those of its part inside the child; when clipping leaves nothing,
//! Akenine-Moller's separating-axis test decides. Clipped bounds are widened by a few
//! ulps where clipping rounded, so a primitive is never left out of a cell it touches.

use super::child_cells;
use crate::geom::Aabb;
use glam::{Vec3, Vec3A};

pub(super) fn intersect_boxes(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb::new(a.min.max(b.min), a.max.min(b.max))
}

/// Relative widening of coordinates that clipping computed (a few ulps of f32).
const CLIP_SLACK: f32 = 1e-6;

/// Room for a triangle clipped by seven planes (3 + 7 corners); a polygon that rounding
/// made more ragged than that takes the exact overlap test's answer instead.
const CLIP_VERTICES: usize = 10;

/// The point where the edge from `a` to `b` crosses the plane `p[axis] = plane`, put
/// exactly on it; [`Polygon::clip`] and [`Polygon::split_bounds`] share it so both cut alike.
#[inline]
fn crossing(a: &[f32; 3], b: &[f32; 3], axis: usize, plane: f32) -> [f32; 3] {
    let p = crossing_a(Vec3A::from_array(*a), Vec3A::from_array(*b), axis, plane);
    p.to_array()
}

/// [`crossing`] in a 4-lane vector: the same operations per component, so the same bits.
#[inline]
fn crossing_a(a: Vec3A, b: Vec3A, axis: usize, plane: f32) -> Vec3A {
    let t = (plane - a[axis]) / (b[axis] - a[axis]);
    let mut p = a + (b - a) * t;
    p[axis] = plane;
    p
}

/// A convex polygon being clipped (Sutherland-Hodgman): its corners, and a bit per
/// corner set when the corner is one of the triangle's own rather than computed.
#[derive(Clone, Copy)]
struct Polygon {
    corners: [[f32; 3]; CLIP_VERTICES],
    exact: u32,
    len: usize,
}

impl Polygon {
    fn triangle(tri: [Vec3; 3]) -> Polygon {
        let mut corners = [[0.0; 3]; CLIP_VERTICES];
        for (c, p) in corners.iter_mut().zip(tri) {
            *c = p.to_array();
        }
        Polygon {
            corners,
            exact: 0b111,
            len: 3,
        }
    }

    /// The part with `p[axis] <= plane` (`keep_below`) or `>= plane`. `None` when
    /// rounding made the polygon so ragged that it would overflow the corner array.
    fn clip(&self, axis: usize, plane: f32, keep_below: bool) -> Option<Polygon> {
        let inside = |p: &[f32; 3]| {
            if keep_below {
                p[axis] <= plane
            } else {
                p[axis] >= plane
            }
        };
        let len = self.len;
        let corners = &self.corners[..len];
        // Bit i: corner i is on the kept side.
        let mut kept = 0u32;
        for (i, p) in corners.iter().enumerate() {
            kept |= (inside(p) as u32) << i;
        }
        if kept == (1 << len) - 1 {
            return Some(*self);
        }
        let mut out = Polygon {
            corners: [[0.0; 3]; CLIP_VERTICES],
            exact: 0,
            len: 0,
        };
        let mut n = 0;
        for (i, a) in corners.iter().enumerate() {
            let j = if i + 1 == len { 0 } else { i + 1 };
            let (a_in, b_in) = (kept >> i & 1, kept >> j & 1);
            if a_in == 1 {
                *out.corners.get_mut(n)? = *a;
                out.exact |= (self.exact >> i & 1) << n;
                n += 1;
            }
            if a_in != b_in {
                *out.corners.get_mut(n)? = crossing(a, &corners[j], axis, plane);
                n += 1;
            }
        }
        out.len = n;
        Some(out)
    }

    /// Bounds of the parts with `p[axis] <= plane` and with `p[axis] >= plane` (empty
    /// for a side with no corner), as [`Polygon::clip`] and [`Polygon::bounds_in`] give
    /// them for each side, in one pass that builds no polygon and computes each point
    /// where an edge crosses the plane once for both (the division is the clipper's
    /// slowest step). `scale` as in [`Polygon::bounds_in`].
    fn split_bounds(&self, axis: usize, plane: f32, scale: Vec3) -> [Aabb; 2] {
        let len = self.len;
        let corners = &self.corners[..len];
        // Bit i: corner i is on the part's side.
        let (mut below, mut above) = (0u32, 0u32);
        for (i, p) in corners.iter().enumerate() {
            below |= ((p[axis] <= plane) as u32) << i;
            above |= ((p[axis] >= plane) as u32) << i;
        }
        let mut parts = [Aabb::EMPTY; 2];
        for (i, a) in corners.iter().enumerate() {
            let j = if i + 1 == len { 0 } else { i + 1 };
            let exact = self.exact >> i & 1 == 1;
            for (part, kept) in parts.iter_mut().zip([below, above]) {
                if kept >> i & 1 == 1 {
                    grow_corner(part, *a, exact, scale);
                }
            }
            let cuts = |kept: u32| (kept >> i & 1) != (kept >> j & 1);
            let (cuts_below, cuts_above) = (cuts(below), cuts(above));
            if cuts_below || cuts_above {
                let p = crossing(a, &corners[j], axis, plane);
                for (part, cut) in parts.iter_mut().zip([cuts_below, cuts_above]) {
                    if cut {
                        grow_corner(part, p, false, scale);
                    }
                }
            }
        }
        parts
    }

    /// The part inside `cell`, clipping only by the faces that cut `whole`, the bounds
    /// of the triangle the polygon came from (the others leave it whole).
    fn clip_to_cell(self, whole: &Aabb, cell: &Aabb) -> Option<Polygon> {
        let mut poly = self;
        for axis in 0..3 {
            if whole.min[axis] < cell.min[axis] {
                poly = poly.clip(axis, cell.min[axis], false)?;
            }
            if whole.max[axis] > cell.max[axis] {
                poly = poly.clip(axis, cell.max[axis], true)?;
            }
            if poly.len == 0 {
                return None;
            }
        }
        Some(poly)
    }

    /// Bounds of the corners in `cell`: the triangle's own count exactly, computed ones
    /// are widened by a few ulps of `scale`, the triangle's largest coordinate. `None`
    /// when the polygon is empty.
    fn bounds_in(&self, scale: Vec3, cell: &Aabb) -> Option<Aabb> {
        if self.len == 0 {
            return None;
        }
        let mut b = Aabb::EMPTY;
        for (i, &p) in self.corners[..self.len].iter().enumerate() {
            grow_corner(&mut b, p, self.exact >> i & 1 == 1, scale);
        }
        let b = intersect_boxes(&b, cell);
        (!b.is_empty()).then_some(b)
    }
}

/// Grows `b` by corner `p`: exactly when it is one of the triangle's own (`exact`), else
/// widened by a few ulps of `scale`, the triangle's largest coordinate.
#[inline]
fn grow_corner(b: &mut Aabb, p: [f32; 3], exact: bool, scale: Vec3) {
    let p = Vec3::from_array(p);
    if exact {
        b.grow(p);
    } else {
        let widen = p.abs().max(scale) * CLIP_SLACK;
        b.grow(p - widen);
        b.grow(p + widen);
    }
}

/// When clipping leaves nothing (or, in theory, rounding makes the polygon ragged),
/// Akenine-Moller's test on `cell` widened by [`CLIP_SLACK`] decides; if it finds a
/// sliver that rounding lost, the triangle's bounds `whole` in the cell are the safe
/// answer.
fn overlap_fallback(tri: [Vec3; 3], whole: &Aabb, cell: &Aabb) -> Option<Aabb> {
    let centre = (cell.min + cell.max) * 0.5;
    let half = (cell.max - cell.min) * 0.5;
    let slack = (centre.abs() + half) * CLIP_SLACK;
    if tri_box_overlap(centre, half + slack, tri) {
        Some(intersect_boxes(whole, cell)).filter(|b| !b.is_empty())
    } else {
        None
    }
}

fn triangle_bounds(tri: &[Vec3; 3]) -> Aabb {
    let mut whole = Aabb::EMPTY;
    tri.iter().for_each(|&p| whole.grow(p));
    whole
}

fn contains(cell: &Aabb, b: &Aabb) -> bool {
    b.min.cmpge(cell.min).all() && b.max.cmple(cell.max).all()
}

/// Bounds of the part of triangle `tri` inside `cell`, or `None` when they do not meet.
///
/// The triangle is clipped to the cell (Sutherland-Hodgman); when nothing is left,
/// Akenine-Moller's exact overlap test (on the cell widened by `CLIP_SLACK`) has the
/// last word, so rounding in the clipper never drops a triangle that touches the cell.
/// Corners of the triangle count exactly; points that clipping computed are widened by
/// a few ulps, and the result is intersected with the cell.
pub fn clip_triangle(tri: [Vec3; 3], cell: &Aabb) -> Option<Aabb> {
    let whole = triangle_bounds(&tri);
    if contains(cell, &whole) {
        return Some(whole);
    }
    let scale = whole.min.abs().max(whole.max.abs());
    Polygon::triangle(tri)
        .clip_to_cell(&whole, cell)
        .and_then(|p| p.bounds_in(scale, cell))
        .or_else(|| overlap_fallback(tri, &whole, cell))
}

/// [`clip_triangle`] for both children of `cell` split at `pos` on `axis`: the triangle
/// is clipped to `cell` once, and that polygon cut by the plane for each side.
pub fn split_triangle(tri: [Vec3; 3], cell: &Aabb, axis: usize, pos: f32) -> [Option<Aabb>; 2] {
    let whole = triangle_bounds(&tri);
    let scale = whole.min.abs().max(whole.max.abs());
    let (left_cell, right_cell) = child_cells(cell, axis, pos);
    // A triangle inside the cell (most straddlers of large cells) needs no clipping: its
    // corners split as the polygon's would.
    let parts = if contains(cell, &whole) {
        split_corners(&tri.map(Vec3A::from), axis, pos, scale.into()).map(Box3::to_aabb)
    } else {
        Polygon::triangle(tri)
            .clip_to_cell(&whole, cell)
            .map_or([Aabb::EMPTY; 2], |p| p.split_bounds(axis, pos, scale))
    };
    let mut bounds = [None; 2];
    for ((b, part), child) in bounds.iter_mut().zip(&parts).zip([left_cell, right_cell]) {
        *b = if contains(&child, &whole) {
            Some(whole)
        } else {
            Some(intersect_boxes(part, &child))
                .filter(|b| !b.is_empty())
                .or_else(|| overlap_fallback(tri, &whole, &child))
        };
    }
    bounds
}

/// [`split_triangle`] for a triangle whose part in `cell` is known to lie in `part`:
/// the triangle is cut by the split plane alone, and each side's bounds are met with
/// `part` and the child's cell. The result contains the exact one (every point of the
/// triangle in the child is in it), is a little looser where several faces of the cell
/// cut the triangle, and costs a fraction of clipping to the cell first.
#[inline(always)]
pub fn split_triangle_within(
    tri: [Vec3; 3],
    part: &Aabb,
    cell: &Aabb,
    axis: usize,
    pos: f32,
) -> [Option<Aabb>; 2] {
    // In 4-lane vectors (`Vec3A`): the same operations in the same order as on `Vec3`
    // (glam's min and max pick alike on ties and NaN), so the same bits.
    let t = tri.map(Vec3A::from);
    let whole = Box3 {
        min: t[0].min(t[1]).min(t[2]),
        max: t[0].max(t[1]).max(t[2]),
    };
    let scale = whole.min.abs().max(whole.max.abs());
    let parts = split_corners(&t, axis, pos, scale);
    let (part, cell) = (Box3::of(part), Box3::of(cell));
    let mut bounds = [None; 2];
    for (side, (b, cut)) in bounds.iter_mut().zip(&parts).enumerate() {
        let mut child = cell;
        if side == 0 {
            child.max[axis] = pos;
        } else {
            child.min[axis] = pos;
        }
        let region = part.meet(&child);
        if region.is_empty() {
            continue;
        }
        let b_cut = cut.meet(&region);
        *b = if b_cut.is_empty() {
            overlap_fallback(tri, &whole.to_aabb(), &region.to_aabb())
        } else {
            Some(b_cut.to_aabb())
        };
    }
    bounds
}

/// A box in 4-lane vectors, for [`split_triangle_within`].
#[derive(Clone, Copy)]
struct Box3 {
    min: Vec3A,
    max: Vec3A,
}

impl Box3 {
    const EMPTY: Box3 = Box3 {
        min: Vec3A::INFINITY,
        max: Vec3A::NEG_INFINITY,
    };

    fn of(b: &Aabb) -> Box3 {
        Box3 {
            min: b.min.into(),
            max: b.max.into(),
        }
    }

    fn to_aabb(self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }

    /// [`intersect_boxes`].
    #[inline]
    fn meet(&self, other: &Box3) -> Box3 {
        Box3 {
            min: self.min.max(other.min),
            max: self.max.min(other.max),
        }
    }

    /// [`Aabb::is_empty`].
    #[inline]
    fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    #[inline]
    fn grow(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// [`grow_corner`] for a computed corner.
    #[inline]
    fn grow_widened(&mut self, p: Vec3A, scale: Vec3A) {
        let widen = p.abs().max(scale) * CLIP_SLACK;
        self.grow(p - widen);
        self.grow(p + widen);
    }
}

/// [`Polygon::split_bounds`] of a whole triangle (every corner its own), unrolled for its
/// three corners: the same bounds without the polygon's corner loop.
#[inline]
fn split_corners(tri: &[Vec3A; 3], axis: usize, plane: f32, scale: Vec3A) -> [Box3; 2] {
    let below = tri.map(|p| p[axis] <= plane);
    let above = tri.map(|p| p[axis] >= plane);
    let mut parts = [Box3::EMPTY; 2];
    for i in 0..3 {
        let j = if i == 2 { 0 } else { i + 1 };
        if below[i] {
            parts[0].grow(tri[i]);
        }
        if above[i] {
            parts[1].grow(tri[i]);
        }
        let (cuts_below, cuts_above) = (below[i] != below[j], above[i] != above[j]);
        if cuts_below || cuts_above {
            let p = crossing_a(tri[i], tri[j], axis, plane);
            if cuts_below {
                parts[0].grow_widened(p, scale);
            }
            if cuts_above {
                parts[1].grow_widened(p, scale);
            }
        }
    }
    parts
}

/// Akenine-Moller's triangle/box overlap test (2001): the separating axis theorem over
/// the box's three axes, the triangle's normal and the nine edge cross products.
pub fn tri_box_overlap(centre: Vec3, half: Vec3, tri: [Vec3; 3]) -> bool {
    let v = tri.map(|p| p - centre);
    for axis in 0..3 {
        let lo = v[0][axis].min(v[1][axis]).min(v[2][axis]);
        let hi = v[0][axis].max(v[1][axis]).max(v[2][axis]);
        if lo > half[axis] || hi < -half[axis] {
            return false;
        }
    }
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    let normal = edges[0].cross(edges[1]);
    let d = normal.dot(v[0]);
    let r = half.dot(normal.abs());
    if d > r || d < -r {
        return false;
    }
    for e in edges {
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let a = axis.cross(e);
            let p = v.map(|x| a.dot(x));
            let lo = p[0].min(p[1]).min(p[2]);
            let hi = p[0].max(p[1]).max(p[2]);
            let r = half.dot(a.abs());
            if lo > r || hi < -r {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_gives_the_part_inside_the_cell() {
        let tri = [
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
        ];
        let cell = Aabb::new(Vec3::new(1.0, 1.0, -1.0), Vec3::new(5.0, 5.0, 1.0));
        let b = clip_triangle(tri, &cell).expect("overlaps");
        // The part with x >= 1, y >= 1 is the triangle (1,1) (3,1) (1,3).
        assert!((b.min - Vec3::new(1.0, 1.0, 0.0)).abs().max_element() < 1e-5);
        assert!((b.max - Vec3::new(3.0, 3.0, 0.0)).abs().max_element() < 1e-5);
        assert!(b.min.x >= 1.0 && b.min.y >= 1.0 && b.max.x >= 3.0 && b.max.y >= 3.0);
        // A cell beyond the hypotenuse: the bounds overlap, the triangle does not.
        let beyond = Aabb::new(Vec3::new(2.5, 2.5, -1.0), Vec3::new(5.0, 5.0, 1.0));
        assert_eq!(clip_triangle(tri, &beyond), None);
        // Touching the cell at one corner still counts.
        let corner = Aabb::new(Vec3::new(4.0, -1.0, -1.0), Vec3::new(5.0, 0.0, 1.0));
        assert!(clip_triangle(tri, &corner).is_some());
    }

    #[test]
    fn triangles_inside_the_cell_split_as_their_polygons() {
        let mut rng = crate::scene::generate::Rng::new(8);
        let mut checked = 0;
        for k in 0..20_000 {
            let mut tri = [0; 3].map(|_| rng.point(Vec3::splat(-1.0), Vec3::ONE));
            let axis = (rng.next_u64() % 3) as usize;
            // Some corners exactly on the plane, some triangles flat in it.
            let pos = rng.range(-1.0, 1.0);
            if k % 5 == 0 {
                tri[k % 3][axis] = pos;
            }
            if k % 17 == 0 {
                tri.iter_mut().for_each(|p| p[axis] = pos);
            }
            let whole = triangle_bounds(&tri);
            // The cell holds the triangle, sometimes touching it.
            let margin = if k % 3 == 0 { 0.0 } else { 0.5 };
            let cell = Aabb::new(whole.min - margin, whole.max + margin);
            if !(pos > cell.min[axis] && pos < cell.max[axis]) {
                continue;
            }
            checked += 1;
            let scale = whole.min.abs().max(whole.max.abs());
            let polygon = Polygon::triangle(tri).split_bounds(axis, pos, scale);
            let corners = split_corners(&tri.map(Vec3A::from), axis, pos, scale.into());
            for (p, c) in polygon.iter().zip(corners) {
                let bits = |b: &Aabb| {
                    (
                        b.min.to_array().map(f32::to_bits),
                        b.max.to_array().map(f32::to_bits),
                    )
                };
                assert_eq!(bits(p), bits(&c.to_aabb()), "{tri:?} {axis} {pos}");
            }
        }
        assert!(checked > 10_000, "{checked}");
    }

    #[test]
    fn cutting_by_the_plane_alone_contains_the_exact_split() {
        let mut rng = crate::scene::generate::Rng::new(7);
        // Both results are widened by up to CLIP_SLACK of the coordinates (at most 1 here)
        // around the true part, each from its own rounded corners: the loose bounds must
        // hold the exact ones up to that widening.
        let tol = 3.0 * CLIP_SLACK;
        let contains_box = |outer: &Aabb, inner: &Aabb| {
            (inner.min + tol).cmpge(outer.min).all() && (inner.max - tol).cmple(outer.max).all()
        };
        let mut straddlers = 0;
        for _ in 0..20_000 {
            let tri = [0; 3].map(|_| {
                Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                )
            });
            let a = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let b = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            let cell = Aabb::new(a.min(b), a.max(b));
            let Some(part) = clip_triangle(tri, &cell) else {
                continue;
            };
            let axis = (rng.next_u64() % 3) as usize;
            let pos = rng.range(part.min[axis], part.max[axis]);
            if !(pos > part.min[axis] && pos < part.max[axis]) {
                continue;
            }
            straddlers += 1;
            let exact = split_triangle(tri, &cell, axis, pos);
            let within = split_triangle_within(tri, &part, &cell, axis, pos);
            for (e, w) in exact.iter().zip(&within) {
                if let Some(e) = e {
                    let w = w.unwrap_or_else(|| panic!("{tri:?} {cell:?} {axis} {pos}: lost"));
                    assert!(
                        contains_box(&w, e),
                        "{tri:?} {cell:?} {axis} {pos}: {w:?} {e:?}"
                    );
                }
            }
        }
        assert!(straddlers > 5_000, "only {straddlers} straddlers");
    }
}
