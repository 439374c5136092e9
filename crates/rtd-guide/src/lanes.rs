//! The triangle pass's test, sixteen triangles at a time: camera space, the projection and the
//! sample test computed lane-wise (one AVX-512 register holds a value for each of sixteen
//! triangles), with the scalar code's own arithmetic, so every lane's answer and screen
//! vertices are bit for bit what the one-triangle path computes for that triangle alone.
//!
//! A dense mesh asks this of millions of triangles, most of which draw nothing: on a
//! 2M-triangle mesh at 256², four in five fall between the samples. Done one triangle at a
//! time the test costs about a hundred cycles (nine divisions, an f64 area, a dozen compares);
//! in lanes, a few.

use glam::Vec3;
use rtd_scene::Triangle;

use crate::projection::{signed_area, Projector};

/// Whether the CPU has the AVX-512 subsets (F, VL, BW, DQ) that the guide's lane-wise loops
/// are compiled for where it does (the triangle pass and tile drawing).
#[cfg(target_arch = "x86_64")]
pub(crate) fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && std::arch::is_x86_feature_detected!("avx512bw")
        && std::arch::is_x86_feature_detected!("avx512dq")
}

/// Triangles tested together.
pub(crate) const LANES: usize = 16;

/// One coordinate of one vertex across the lanes.
type Lane = [f32; LANES];

/// What the test says of each of up to [`LANES`] triangles.
pub(crate) struct LaneVerdicts {
    /// Screen x, y and depth key of each vertex ([`Projector::to_screen`]), by vertex, then
    /// coordinate, then lane; meaningful in the lanes [`keep`](Self::keep) marks.
    pub(crate) v: [[Lane; 3]; 3],
    /// The triangle lies whole in front of the near plane, its screen vertices are finite, and
    /// it draws a sample's worth ([`Projector::draws_a_sample`]).
    pub(crate) keep: [bool; LANES],
    /// The triangle crosses the near plane: the one-triangle path clips it.
    pub(crate) clip: [bool; LANES],
}

impl LaneVerdicts {
    /// The screen vertices of lane `l`.
    #[inline(always)]
    pub(crate) fn vertices(&self, l: usize) -> [Vec3; 3] {
        [0, 1, 2].map(|k| Vec3::new(self.v[k][0][l], self.v[k][1][l], self.v[k][2][l]))
    }
}

impl Projector<'_> {
    /// Tests `tris` (at most [`LANES`]; lanes past its end say neither keep nor clip).
    #[inline(always)]
    pub(crate) fn test_lanes(&self, tris: &[Triangle]) -> LaneVerdicts {
        debug_assert!(tris.len() <= LANES);
        // Gather the positions lane-wise: p[vertex][axis][lane].
        let mut p = [[[0.0f32; LANES]; 3]; 3];
        for (l, t) in tris.iter().enumerate() {
            for (k, q) in t.p.iter().enumerate() {
                p[k][0][l] = q.x;
                p[k][1][l] = q.y;
                p[k][2][l] = q.z;
            }
        }
        let mut out = LaneVerdicts { v: [[[0.0; LANES]; 3]; 3], keep: [false; LANES], clip: [false; LANES] };
        if self.persp {
            self.test_projected::<true>(&p, &mut out);
        } else {
            self.test_projected::<false>(&p, &mut out);
        }
        for l in tris.len()..LANES {
            out.keep[l] = false;
            out.clip[l] = false;
        }
        out
    }

    /// The lane-wise body of [`Projector::test_lanes`] for one projection (a constant, so its
    /// loops do not branch on it).
    #[inline(always)]
    fn test_projected<const PERSP: bool>(&self, p: &[[Lane; 3]; 3], out: &mut LaneVerdicts) {
        let cam = self.cam;
        let (w, h) = (self.width as f32, self.height as f32);
        let mut front = [true; LANES];
        let mut behind = [true; LANES];
        for (pk, vk) in p.iter().zip(out.v.iter_mut()) {
            for l in 0..LANES {
                // Camera space (`to_camera`): the offset from the eye dotted with the camera's
                // axes, summed left to right as glam's dot sums.
                let d = Vec3::new(pk[0][l], pk[1][l], pk[2][l]) - cam.position;
                let dot = |a: Vec3| d.x * a.x + d.y * a.y + d.z * a.z;
                let (cx, cy, cz) = (dot(cam.right), dot(cam.up), dot(cam.forward));
                front[l] &= cz >= self.near;
                behind[l] &= cz < self.near;
                // Screen x, y and depth key (`Projector::to_screen`).
                let (nx, ny, key) = if PERSP {
                    (cx * self.sx / cz, cy * self.sy / cz, 1.0 / cz)
                } else {
                    (cx * self.sx, cy * self.sy, -cz)
                };
                vk[0][l] = (nx + 1.0) * 0.5 * w;
                vk[1][l] = (1.0 - ny) * 0.5 * h;
                vk[2][l] = key;
            }
        }
        for l in 0..LANES {
            let v = out.vertices(l);
            let finite = v.iter().fold(true, |f, q| f & q.is_finite());
            out.keep[l] = front[l] & finite & self.draws_a_sample(&v, signed_area(&v));
            out.clip[l] = !front[l] & !behind[l];
        }
    }
}
