//! A light BVH (Conty Estevez and Kulla 2018, as pbrt-v4's `BVHLightSampler`): the lights with
//! a position (emissive triangles, point and spot lights) in a binary tree whose nodes bound
//! their lights' positions, emission directions and power. A shading point picks a light by
//! walking down from the root, choosing each child in proportion to an upper bound of what it
//! can contribute there: power over squared distance, cut by the angle between the point and
//! the lights' emission cones and by the cosine at the receiving surface. Far, turned-away or
//! dim groups of lights are then rarely picked, which power-proportional selection cannot do.

use glam::Vec3;
use std::f32::consts::PI;

/// What a node knows of its lights: where they are, where they shine, and how much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    /// Lower corner of the box holding the lights.
    pub lo: Vec3,
    /// Upper corner.
    pub hi: Vec3,
    /// Axis of the cone holding the lights' normals (or spot axes).
    pub w: Vec3,
    /// Total power (luminance).
    pub phi: f32,
    /// Cosine of the half angle of the normal cone about `w`.
    pub cos_o: f32,
    /// Cosine of the largest angle past the normal cone at which a light still emits (π/2 for
    /// an area light: cos = 0).
    pub cos_e: f32,
    /// Whether some light emits from both sides.
    pub two_sided: bool,
}

/// sin from cos, clamped.
#[inline]
fn sin_of(cos: f32) -> f32 {
    (1.0 - cos * cos).max(0.0).sqrt()
}

/// cos(max(0, a − b)) from the sines and cosines of a and b.
#[inline]
fn cos_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// sin(max(0, a − b)) from the sines and cosines of a and b.
#[inline]
fn sin_sub_clamped(sin_a: f32, cos_a: f32, sin_b: f32, cos_b: f32) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

impl LightBounds {
    /// The bounds of one emissive triangle facing `normal`.
    pub fn triangle(p: [Vec3; 3], normal: Vec3, phi: f32, two_sided: bool) -> Self {
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        LightBounds { lo, hi, w: normal, phi, cos_o: 1.0, cos_e: 0.0, two_sided }
    }

    /// The bounds of a light at `position` shining into the cone about `axis` of cosine
    /// `cos_cone` (a point light: any axis, cosine −1).
    pub fn point(position: Vec3, axis: Vec3, cos_cone: f32, phi: f32) -> Self {
        LightBounds { lo: position, hi: position, w: axis, phi, cos_o: cos_cone, cos_e: 0.0, two_sided: false }
    }

    /// The bounds of both.
    pub fn union(&self, o: &LightBounds) -> LightBounds {
        let (w, cos_o) = cone_union((self.w, self.cos_o), (o.w, o.cos_o));
        LightBounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            w,
            phi: self.phi + o.phi,
            cos_o,
            cos_e: self.cos_e.min(o.cos_e),
            two_sided: self.two_sided || o.two_sided,
        }
    }

    fn centre(&self) -> Vec3 {
        (self.lo + self.hi) * 0.5
    }

    /// An upper bound of the contribution of these lights at point `p` with surface normal `n`
    /// (zero for none), up to a common factor: Φ · cos θ' / d², where θ' is the smallest angle
    /// between the lights' emission cone and the direction to `p` that the box allows, times
    /// the smallest incidence cosine the box allows at `p`.
    pub fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        let pc = self.centre();
        // Distance to the centre, no less than half the box's diagonal (a point inside).
        let d2 = p.distance_squared(pc).max((self.hi - self.lo).length() * 0.5);
        let wi = (p - pc).normalize_or_zero();
        let mut cos_w = self.w.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let sin_w = sin_of(cos_w);
        // The half angle the box subtends from p.
        let cos_b = self.subtended_cos(p);
        let sin_b = sin_of(cos_b);
        // θ' = max(0, θ_w − θ_o − θ_b).
        let sin_o = sin_of(self.cos_o);
        let cos_x = cos_sub_clamped(sin_w, cos_w, sin_o, self.cos_o);
        let sin_x = sin_sub_clamped(sin_w, cos_w, sin_o, self.cos_o);
        let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_p / d2;
        if n != Vec3::ZERO {
            // The incidence angle at p, less the box's half angle.
            let cos_i = wi.dot(n).abs();
            importance *= cos_sub_clamped(sin_of(cos_i), cos_i, sin_b, cos_b);
        }
        importance.max(0.0)
    }

    /// Cosine of the half angle of the cone of directions from `p` that meets the box (−1 when
    /// `p` is inside the box's bounding sphere).
    fn subtended_cos(&self, p: Vec3) -> f32 {
        let (c, r2) = (self.centre(), (self.hi - self.lo).length_squared() * 0.25);
        let d2 = p.distance_squared(c);
        if d2 < r2 {
            return -1.0;
        }
        (1.0 - r2 / d2).max(0.0).sqrt()
    }

    /// The build's cost of a node with these bounds, split along `dim` of a box `extent`:
    /// power × the solid angle its emission covers × its area (the surface area orientation
    /// heuristic), stretched for thin boxes.
    fn cost(&self, extent: Vec3, dim: usize) -> f32 {
        let theta_o = self.cos_o.clamp(-1.0, 1.0).acos();
        let theta_e = self.cos_e.clamp(-1.0, 1.0).acos();
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = sin_of(self.cos_o);
        // M_Ω: the cosine-weighted solid angle of the cone of emission.
        let m_omega = 2.0 * PI * (1.0 - self.cos_o)
            + PI / 2.0 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + self.cos_o);
        let kr = extent.max_element() / extent[dim].max(f32::MIN_POSITIVE);
        let e = self.hi - self.lo;
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        self.phi * m_omega * kr * area.max(f32::MIN_POSITIVE)
    }
}

/// The smallest cone (axis, cosine) holding two cones.
fn cone_union(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let (theta_a, theta_b) = (a.1.clamp(-1.0, 1.0).acos(), b.1.clamp(-1.0, 1.0).acos());
    let theta_d = a.0.dot(b.0).clamp(-1.0, 1.0).acos();
    if (theta_d + theta_b).min(PI) <= theta_a {
        return a;
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return b;
    }
    let theta_o = (theta_a + theta_d + theta_b) * 0.5;
    if theta_o >= PI {
        return (a.0, -1.0);
    }
    // Rotate a's axis towards b's by θ_o − θ_a.
    let wr = a.0.cross(b.0);
    if wr.length_squared() == 0.0 {
        return (a.0, -1.0);
    }
    let w = glam::Quat::from_axis_angle(wr.normalize(), theta_o - theta_a) * a.0;
    (w.normalize(), theta_o.cos())
}

/// A node's bounds in the form [`NodeBounds::importance`] reads, with what it derives from
/// them worked out once at build time.
#[derive(Clone, Copy, Debug)]
struct NodeBounds {
    centre: Vec3,
    /// Squared radius of the box's bounding sphere.
    radius2: f32,
    /// Half the box's diagonal: the least distance² the importance assumes (as pbrt does).
    half_diagonal: f32,
    w: Vec3,
    phi: f32,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    two_sided: bool,
}

impl NodeBounds {
    fn new(b: &LightBounds) -> Self {
        let diagonal = b.hi - b.lo;
        NodeBounds {
            centre: b.centre(),
            radius2: diagonal.length_squared() * 0.25,
            half_diagonal: diagonal.length() * 0.5,
            w: b.w,
            phi: b.phi,
            cos_o: b.cos_o,
            sin_o: sin_of(b.cos_o),
            cos_e: b.cos_e,
            two_sided: b.two_sided,
        }
    }

    /// [`LightBounds::importance`], the same arithmetic on the precomputed values.
    #[inline]
    fn importance(&self, p: Vec3, n: Vec3) -> f32 {
        let to_p = p - self.centre;
        let dist2 = to_p.length_squared();
        let d2 = dist2.max(self.half_diagonal);
        let wi = if dist2 > 0.0 { to_p / dist2.sqrt() } else { Vec3::ZERO };
        let mut cos_w = self.w.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let sin_w = sin_of(cos_w);
        // The half angle the box subtends from p (all directions from inside its sphere).
        let (cos_b, sin_b) = if dist2 < self.radius2 {
            (-1.0, 0.0)
        } else {
            let s2 = self.radius2 / dist2;
            ((1.0 - s2).max(0.0).sqrt(), s2.sqrt())
        };
        let cos_x = cos_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
        let sin_x = sin_sub_clamped(sin_w, cos_w, self.sin_o, self.cos_o);
        let cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_p / d2;
        if n != Vec3::ZERO {
            let cos_i = wi.dot(n).abs();
            importance *= cos_sub_clamped(sin_of(cos_i), cos_i, sin_b, cos_b);
        }
        importance.max(0.0)
    }
}

/// A node: its bounds, and either two children (the first right after it, the second at
/// `index`) or one light (`index`).
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: NodeBounds,
    /// Index of the second child (interior), or of the light (leaf).
    index: u32,
    leaf: bool,
}

/// The tree over a set of bounded lights.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
    /// Per light: the left/right choices from the root to its leaf (bit k = the choice at
    /// depth k, 1 for the second child), and the depth.
    trail: Vec<(u64, u8)>,
}

/// Buckets per axis when splitting.
const BUCKETS: usize = 12;

impl LightTree {
    /// Builds the tree over `lights` (bounds with positive power), indexed as given.
    pub fn new(lights: &[LightBounds]) -> Self {
        let mut tree = LightTree { nodes: Vec::with_capacity(2 * lights.len()), trail: vec![(0, 0); lights.len()] };
        if !lights.is_empty() {
            let mut items: Vec<u32> = (0..lights.len() as u32).collect();
            tree.build(lights, &mut items, 0, 0);
        }
        tree
    }

    /// True without lights.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Builds the subtree of `items` (whose root is reached by `bits` over `depth` levels);
    /// returns its root's bounds.
    fn build(&mut self, lights: &[LightBounds], items: &mut [u32], bits: u64, depth: u8) -> LightBounds {
        let at = self.nodes.len();
        if let [i] = items {
            self.trail[*i as usize] = (bits, depth);
            self.nodes.push(Node { bounds: NodeBounds::new(&lights[*i as usize]), index: *i, leaf: true });
            return lights[*i as usize];
        }
        // Past 32 levels the lights are split in halves, so no trail outgrows its 64 bits.
        let split = if depth < 32 { split(lights, items) } else { items.len() / 2 };
        self.nodes.push(Node { bounds: NodeBounds::new(&lights[items[0] as usize]), index: 0, leaf: false });
        let (left, right) = items.split_at_mut(split);
        let a = self.build(lights, left, bits, depth + 1);
        let second = self.nodes.len() as u32;
        let b = self.build(lights, right, bits | (1 << depth), depth + 1);
        let bounds = a.union(&b);
        self.nodes[at] = Node { bounds: NodeBounds::new(&bounds), index: second, leaf: false };
        bounds
    }

    /// Picks a light for a point `p` with normal `n` (zero for none) with `u` in [0, 1):
    /// returns (light index, probability), or None where no light can contribute.
    pub fn sample(&self, p: Vec3, n: Vec3, mut u: f32) -> Option<(u32, f32)> {
        let (mut node, mut pmf) = (0usize, 1.0f32);
        loop {
            let nd = self.nodes.get(node)?;
            if nd.leaf {
                return (node > 0 || nd.bounds.importance(p, n) > 0.0).then_some((nd.index, pmf));
            }
            let (c0, c1) = (node + 1, nd.index as usize);
            let (i0, i1) = (self.nodes[c0].bounds.importance(p, n), self.nodes[c1].bounds.importance(p, n));
            if !(i0 + i1 > 0.0) {
                return None;
            }
            let p0 = i0 / (i0 + i1);
            if u < p0 {
                u = (u / p0).min(ONE_MINUS_EPSILON);
                pmf *= p0;
                node = c0;
            } else {
                u = ((u - p0) / (1.0 - p0)).min(ONE_MINUS_EPSILON);
                pmf *= 1.0 - p0;
                node = c1;
            }
        }
    }

    /// The probability that [`LightTree::sample`] at (`p`, `n`) picks light `light`.
    pub fn pmf(&self, p: Vec3, n: Vec3, light: u32) -> f32 {
        let Some(&(bits, depth)) = self.trail.get(light as usize) else { return 0.0 };
        let (mut node, mut pmf) = (0usize, 1.0f32);
        for k in 0..depth {
            let nd = &self.nodes[node];
            let (c0, c1) = (node + 1, nd.index as usize);
            let (i0, i1) = (self.nodes[c0].bounds.importance(p, n), self.nodes[c1].bounds.importance(p, n));
            if !(i0 + i1 > 0.0) {
                return 0.0;
            }
            let second = bits >> k & 1 == 1;
            pmf *= if second { i1 } else { i0 } / (i0 + i1);
            node = if second { c1 } else { c0 };
        }
        pmf
    }
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Where to split `items` (reordering them): the bucket boundary of least cost over the three
/// axes of the centroids' box, or the middle when the centroids coincide.
fn split(lights: &[LightBounds], items: &mut [u32]) -> usize {
    let centre = |i: &u32| lights[*i as usize].centre();
    let (clo, chi) =
        items.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| (lo.min(centre(i)), hi.max(centre(i))));
    let extent = items.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), i| {
        (lo.min(lights[*i as usize].lo), hi.max(lights[*i as usize].hi))
    });
    let extent = extent.1 - extent.0;
    let mut best: Option<(f32, usize, usize)> = None; // (cost, dim, first bucket on the right)
    for dim in 0..3 {
        let (lo, hi) = (clo[dim], chi[dim]);
        if !(hi > lo) {
            continue;
        }
        let bucket = |i: &u32| (((centre(i)[dim] - lo) / (hi - lo) * BUCKETS as f32) as usize).min(BUCKETS - 1);
        let mut bounds: [Option<LightBounds>; BUCKETS] = [None; BUCKETS];
        for i in items.iter() {
            let b = &mut bounds[bucket(i)];
            *b = Some(b.map_or(lights[*i as usize], |x| x.union(&lights[*i as usize])));
        }
        for cut in 1..BUCKETS {
            let side = |r: std::ops::Range<usize>| {
                bounds[r]
                    .iter()
                    .flatten()
                    .fold(None, |acc: Option<LightBounds>, b| Some(acc.map_or(*b, |a| a.union(b))))
            };
            let (Some(l), Some(r)) = (side(0..cut), side(cut..BUCKETS)) else { continue };
            let cost = l.cost(extent, dim) + r.cost(extent, dim);
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, dim, cut));
            }
        }
    }
    let Some((_, dim, cut)) = best else { return items.len() / 2 };
    // Partition by the same bucket arithmetic the cost used: left of the cut first.
    let (lo, hi) = (clo[dim], chi[dim]);
    let bucket = |i: &u32| (((centre(i)[dim] - lo) / (hi - lo) * BUCKETS as f32) as usize).min(BUCKETS - 1);
    items.sort_by_key(|i| (bucket(i) >= cut, *i));
    let mid = items.iter().take_while(|i| bucket(i) < cut).count();
    if mid == 0 || mid == items.len() {
        items.len() / 2
    } else {
        mid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of small downward-facing quads (as triangles) of different powers.
    fn lights() -> Vec<LightBounds> {
        (0..200)
            .map(|i| {
                let (x, z) = ((i % 20) as f32, (i / 20) as f32);
                let p = [Vec3::new(x, 4.0, z), Vec3::new(x + 0.2, 4.0, z), Vec3::new(x, 4.0, z + 0.2)];
                LightBounds::triangle(p, Vec3::NEG_Y, 0.5 + (i % 7) as f32, i % 13 == 0)
            })
            .chain([LightBounds::point(Vec3::new(3.0, 1.0, 3.0), Vec3::Z, -1.0, 20.0)])
            .chain([LightBounds::point(Vec3::new(15.0, 2.0, 8.0), Vec3::NEG_Y, 0.8, 30.0)])
            .collect()
    }

    /// The pmf sums to one where every light can reach the point, and to less where some
    /// provably cannot (lights facing away: their share of the walk ends with no light); every
    /// light that can reach it has a positive pmf, and picks follow the pmf (chi-square).
    #[test]
    fn the_pmf_sums_to_one_and_sampling_follows_it() {
        let ls = lights();
        let tree = LightTree::new(&ls);
        let points = [
            (Vec3::new(2.0, 0.0, 3.0), Vec3::Y, true),
            (Vec3::new(18.0, 1.0, 9.0), Vec3::ZERO, true),
            (Vec3::new(9.0, 6.0, 5.0), Vec3::NEG_Y, false),
        ];
        for (p, n, all_reach) in points {
            let pmf: Vec<f64> = (0..ls.len() as u32).map(|i| tree.pmf(p, n, i) as f64).collect();
            let total: f64 = pmf.iter().sum();
            assert!(total <= 1.0 + 1e-4 && (!all_reach || total >= 1.0 - 1e-4), "pmf sums to {total} at {p}");
            for (i, l) in ls.iter().enumerate() {
                assert!(l.importance(p, n) == 0.0 || pmf[i] > 0.0, "light {i} can reach {p} but is never picked");
            }
            // Chi-square of 200k picks against the pmf (and "none" against 1 − total), over bins
            // expected at least 5 times.
            let draws = 200_000;
            let mut counts = vec![0u64; ls.len() + 1];
            for k in 0..draws {
                let u = (k as f32 + 0.5) / draws as f32;
                match tree.sample(p, n, u) {
                    Some((i, prob)) => {
                        assert!(
                            (prob - tree.pmf(p, n, i)).abs() <= 1e-5 * prob.max(1e-6),
                            "sampled probability {prob}"
                        );
                        counts[i as usize] += 1;
                    }
                    None => counts[ls.len()] += 1,
                }
            }
            let expected = pmf.iter().copied().chain([1.0 - total]);
            let (mut chi2, mut dof) = (0.0, 0);
            for (c, q) in counts.iter().zip(expected) {
                let e = q * draws as f64;
                if e >= 5.0 {
                    chi2 += (*c as f64 - e).powi(2) / e;
                    dof += 1;
                }
            }
            // The draws are stratified, so chi-square lies far below its i.i.d. bound.
            assert!(chi2 < dof as f64 + 4.0 * (2.0 * dof as f64).sqrt(), "chi2 {chi2} over {dof} bins at {p}");
        }
    }

    #[test]
    fn near_lights_are_picked_more_than_far_ones_of_equal_power() {
        let ls: Vec<LightBounds> =
            (0..64).map(|i| LightBounds::point(Vec3::new(i as f32 * 2.0, 3.0, 0.0), Vec3::Z, -1.0, 1.0)).collect();
        let tree = LightTree::new(&ls);
        let p = Vec3::new(0.0, 0.0, 0.0);
        assert!(tree.pmf(p, Vec3::Y, 0) > 20.0 * tree.pmf(p, Vec3::Y, 63));
        // Lights facing away from a point get nothing: a spot aimed up, seen from below.
        let up = LightTree::new(&[
            LightBounds::point(Vec3::new(0.0, 3.0, 0.0), Vec3::Y, 0.9, 1.0),
            LightBounds::point(Vec3::new(1.0, 3.0, 0.0), Vec3::NEG_Y, 0.9, 1.0),
        ]);
        assert_eq!(up.pmf(Vec3::ZERO, Vec3::Y, 0), 0.0);
        assert_eq!(up.pmf(Vec3::ZERO, Vec3::Y, 1), 1.0);
    }

    #[test]
    fn cone_union_holds_both_cones() {
        let (w, c) = cone_union((Vec3::Z, 30f32.to_radians().cos()), (Vec3::X, 10f32.to_radians().cos()));
        for (axis, half) in [(Vec3::Z, 30f32), (Vec3::X, 10f32)] {
            let theta = w.dot(axis).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(theta + half <= c.acos().to_degrees() + 1e-3, "{theta} + {half} > {}", c.acos().to_degrees());
        }
        assert_eq!(cone_union((Vec3::Z, 0.0), (Vec3::Z, 0.5)), (Vec3::Z, 0.0), "the wider cone holds the other");
    }
}
