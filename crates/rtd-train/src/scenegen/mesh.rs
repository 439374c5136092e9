//! Triangle meshes for the procedural scenes: boxes, spheres, cylinders, tori, displaced blobs,
//! strands and panels, built directly in world space.

use glam::{Mat3, Vec2, Vec3};
use std::f32::consts::{PI, TAU};

/// An indexed triangle mesh with smooth or flat normals and UVs.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Texture coordinates.
    pub uvs: Vec<Vec2>,
    /// Three indices per triangle, counter-clockwise seen from the front.
    pub indices: Vec<u32>,
}

impl Mesh {
    fn vertex(&mut self, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        self.uvs.push(uv);
        (self.positions.len() - 1) as u32
    }

    /// A quad `a b c d` (counter-clockwise from the front), UVs scaled by `uv_scale`.
    pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3, uv_scale: f32) -> Mesh {
        let mut m = Mesh::default();
        m.push_quad(a, b, c, d, uv_scale);
        m
    }

    fn push_quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, uv_scale: f32) {
        let n = (b - a).cross(d - a).normalize_or_zero();
        let s = uv_scale;
        let i0 = self.vertex(a, n, Vec2::new(0.0, 0.0));
        let i1 = self.vertex(b, n, Vec2::new(s, 0.0));
        let i2 = self.vertex(c, n, Vec2::new(s, s));
        let i3 = self.vertex(d, n, Vec2::new(0.0, s));
        self.indices.extend_from_slice(&[i0, i1, i2, i0, i2, i3]);
    }

    /// An oriented box: centre, half extents along the columns of `rot`. `inward` flips the faces
    /// so that a camera inside sees them (a room).
    pub fn cuboid(center: Vec3, half: Vec3, rot: Mat3, inward: bool, uv_scale: f32) -> Mesh {
        let mut m = Mesh::default();
        let corner = |sx: f32, sy: f32, sz: f32| center + rot * (half * Vec3::new(sx, sy, sz));
        // Each face as four corners counter-clockwise seen from outside.
        let faces = [
            [(1., -1., -1.), (1., 1., -1.), (1., 1., 1.), (1., -1., 1.)],
            [(-1., -1., 1.), (-1., 1., 1.), (-1., 1., -1.), (-1., -1., -1.)],
            [(-1., 1., -1.), (-1., 1., 1.), (1., 1., 1.), (1., 1., -1.)],
            [(-1., -1., 1.), (-1., -1., -1.), (1., -1., -1.), (1., -1., 1.)],
            [(-1., -1., 1.), (1., -1., 1.), (1., 1., 1.), (-1., 1., 1.)],
            [(1., -1., -1.), (-1., -1., -1.), (-1., 1., -1.), (1., 1., -1.)],
        ];
        for f in faces {
            let mut q = f.map(|(x, y, z)| corner(x, y, z));
            if inward {
                q.reverse();
            }
            m.push_quad(q[0], q[1], q[2], q[3], uv_scale);
        }
        m
    }

    /// A UV sphere whose radius is modulated by `displace(unit direction)` (0 for a plain sphere).
    pub fn sphere(center: Vec3, radius: f32, segments: u32, displace: &dyn Fn(Vec3) -> f32) -> Mesh {
        let (nu, nv) = (segments * 2, segments);
        let dir = |i: u32, j: u32| {
            let th = PI * j as f32 / nv as f32;
            let ph = TAU * i as f32 / nu as f32;
            Vec3::new(th.sin() * ph.cos(), th.cos(), -th.sin() * ph.sin())
        };
        let pos = |d: Vec3| center + d * radius * (1.0 + displace(d));
        let mut m = Mesh::default();
        for j in 0..=nv {
            for i in 0..=nu {
                let d = dir(i, j);
                // Normal from the displaced surface by central differences on the grid.
                let (du, dv) = (
                    pos(dir(i + 1, j)) - pos(dir(i.wrapping_sub(1).min(nu), j)),
                    pos(dir(i, (j + 1).min(nv))) - pos(dir(i, j.saturating_sub(1))),
                );
                let mut n = dv.cross(du).normalize_or_zero();
                if n.dot(d) < 0.0 {
                    n = -n;
                }
                if n == Vec3::ZERO || j == 0 || j == nv {
                    n = d;
                }
                m.vertex(pos(d), n, Vec2::new(i as f32 / nu as f32 * 4.0, j as f32 / nv as f32 * 2.0));
            }
        }
        m.grid_indices(nu, nv, false);
        m
    }

    fn grid_indices(&mut self, nu: u32, nv: u32, flip: bool) {
        let row = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                let (a, b, c, d) = (j * row + i, (j + 1) * row + i, (j + 1) * row + i + 1, j * row + i + 1);
                if flip {
                    self.indices.extend_from_slice(&[a, c, b, a, d, c]);
                } else {
                    self.indices.extend_from_slice(&[a, b, c, a, c, d]);
                }
            }
        }
    }

    /// A capped cylinder of `radius` from `base` along `axis` (its length is the height).
    pub fn cylinder(base: Vec3, axis: Vec3, radius: f32, segments: u32) -> Mesh {
        let h = axis.length();
        let w = axis / h;
        let u = w.any_orthonormal_vector();
        let v = w.cross(u);
        let mut m = Mesh::default();
        for j in 0..=1u32 {
            for i in 0..=segments {
                let ph = TAU * i as f32 / segments as f32;
                let n = u * ph.cos() + v * ph.sin();
                m.vertex(
                    base + w * (h * j as f32) + n * radius,
                    n,
                    Vec2::new(i as f32 / segments as f32 * 3.0, j as f32),
                );
            }
        }
        m.grid_indices(segments, 1, true);
        for (cap_h, normal) in [(0.0, -w), (h, w)] {
            let c = m.vertex(base + w * cap_h, normal, Vec2::splat(0.5));
            let first = m.positions.len() as u32;
            for i in 0..segments {
                let ph = TAU * i as f32 / segments as f32;
                m.vertex(
                    base + w * cap_h + (u * ph.cos() + v * ph.sin()) * radius,
                    normal,
                    Vec2::new(0.5 + 0.5 * ph.cos(), 0.5 + 0.5 * ph.sin()),
                );
            }
            for i in 0..segments {
                let (a, b) = (first + i, first + (i + 1) % segments);
                if normal.dot(w) > 0.0 {
                    m.indices.extend_from_slice(&[c, a, b]);
                } else {
                    m.indices.extend_from_slice(&[c, b, a]);
                }
            }
        }
        m
    }

    /// A torus around `axis` (unit) through `center`: ring radius `major`, tube radius `minor`.
    pub fn torus(center: Vec3, axis: Vec3, major: f32, minor: f32, segments: u32) -> Mesh {
        let w = axis.normalize();
        let u = w.any_orthonormal_vector();
        let v = w.cross(u);
        let (nu, nv) = (segments * 2, segments);
        let mut m = Mesh::default();
        for j in 0..=nv {
            for i in 0..=nu {
                let (ph, th) = (TAU * i as f32 / nu as f32, TAU * j as f32 / nv as f32);
                let radial = u * ph.cos() + v * ph.sin();
                let n = radial * th.cos() + w * th.sin();
                m.vertex(
                    center + radial * major + n * minor,
                    n,
                    Vec2::new(i as f32 / nu as f32 * 6.0, j as f32 / nv as f32 * 2.0),
                );
            }
        }
        m.grid_indices(nu, nv, true);
        m
    }

    /// Appends another mesh.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        self.uvs.extend_from_slice(&other.uvs);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// The same mesh without zero-area triangles (UV-sphere poles, collapsed caps).
    pub fn without_degenerate_triangles(&self) -> Mesh {
        let mut m = self.clone();
        m.indices = self
            .indices
            .chunks(3)
            .filter(|t| {
                let p = [t[0], t[1], t[2]].map(|i| self.positions[i as usize]);
                (p[1] - p[0]).cross(p[2] - p[0]).length_squared() > 1e-14
            })
            .flatten()
            .copied()
            .collect();
        m
    }

    /// The lowest y of any vertex.
    pub fn min_y(&self) -> f32 {
        self.positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed volume by the divergence theorem: positive when faces point outwards.
    fn volume(m: &Mesh) -> f32 {
        m.indices
            .chunks(3)
            .map(|t| {
                let (a, b, c) = (m.positions[t[0] as usize], m.positions[t[1] as usize], m.positions[t[2] as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn closed_shapes_face_outwards_with_the_right_volume() {
        let cube = Mesh::cuboid(Vec3::ZERO, Vec3::splat(0.5), Mat3::IDENTITY, false, 1.0);
        assert!((volume(&cube) - 1.0).abs() < 1e-5);
        let room = Mesh::cuboid(Vec3::ZERO, Vec3::splat(0.5), Mat3::IDENTITY, true, 1.0);
        assert!((volume(&room) + 1.0).abs() < 1e-5);
        let s = Mesh::sphere(Vec3::ZERO, 1.0, 48, &|_| 0.0);
        assert!((volume(&s) - 4.0 / 3.0 * PI).abs() < 0.03, "{}", volume(&s));
        let c = Mesh::cylinder(Vec3::ZERO, Vec3::Y * 2.0, 1.0, 64);
        assert!((volume(&c) - 2.0 * PI).abs() < 0.02, "{}", volume(&c));
        let t = Mesh::torus(Vec3::ZERO, Vec3::Y, 2.0, 0.5, 48);
        assert!((volume(&t) - 2.0 * PI * PI * 2.0 * 0.25).abs() < 0.1, "{}", volume(&t));
    }

    #[test]
    fn normals_agree_with_winding() {
        for m in [
            Mesh::sphere(Vec3::ONE, 0.7, 16, &|d| 0.1 * (5.0 * d.x).sin()),
            Mesh::torus(Vec3::ZERO, Vec3::X, 1.0, 0.3, 16),
            Mesh::cylinder(Vec3::ZERO, Vec3::Z, 0.5, 12),
        ] {
            let mut agree = 0;
            for t in m.indices.chunks(3) {
                let p = [t[0], t[1], t[2]].map(|i| m.positions[i as usize]);
                let g = (p[1] - p[0]).cross(p[2] - p[0]);
                if g.length() < 1e-9 {
                    agree += 1;
                    continue;
                }
                if g.dot(m.normals[t[0] as usize] + m.normals[t[1] as usize] + m.normals[t[2] as usize]) > 0.0 {
                    agree += 1;
                }
            }
            assert!(agree * 100 >= m.indices.len() / 3 * 99, "{agree} of {}", m.indices.len() / 3);
        }
    }
}
