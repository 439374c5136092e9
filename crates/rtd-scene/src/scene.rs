use std::path::Path;

use glam::{Vec2, Vec3, Vec4};

use crate::{Aabb, Camera, Environment, Light, Material, SceneError, TexCoords, Texture};

/// One world-space triangle with per-vertex shading attributes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// Vertex positions; counter-clockwise winding seen from the front.
    pub p: [Vec3; 3],
    /// Unit shading normals per vertex.
    pub n: [Vec3; 3],
    /// Texture coordinates (set 0) per vertex.
    pub uv: [Vec2; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

impl Triangle {
    /// The unnormalised geometric normal (e1 × e2), whose length is twice the area.
    #[inline]
    pub fn cross(&self) -> Vec3 {
        (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0])
    }
    /// Unit geometric normal on the front side. The front is where the vertex normals point
    /// (normals generated from the winding when the file had none), so files whose winding
    /// disagrees with their normals still shade, emit and refract on the intended side.
    #[inline]
    pub fn front_normal(&self) -> Vec3 {
        let n = self.cross().normalize_or_zero();
        if (self.n[0] + self.n[1] + self.n[2]).dot(n) < 0.0 {
            -n
        } else {
            n
        }
    }
    /// The triangle's area.
    pub fn area(&self) -> f32 {
        self.cross().length() * 0.5
    }
}

/// A loaded scene, flattened to world-space triangles.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// All renderable triangles.
    pub triangles: Vec<Triangle>,
    /// Materials referenced by triangles; never empty once loaded.
    pub materials: Vec<Material>,
    /// Decoded textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Cameras in file order.
    pub cameras: Vec<Camera>,
    /// Punctual lights.
    pub lights: Vec<Light>,
    /// Environment lighting (black unless set by the caller).
    pub environment: Environment,
    /// Triangles [`Scene::push_triangle`] refused because a position was NaN/Inf. A file with any
    /// fails to load (no position is right for them), so this counts only in scenes built in code.
    pub skipped_nonfinite: usize,
    /// Triangles dropped at load because they had zero area.
    pub skipped_degenerate: usize,
    /// Non-fatal problems found while loading, one line each.
    pub warnings: Vec<String>,
    /// Linear vertex colours (glTF `COLOR_0`, RGB) per triangle, which multiply the base
    /// colour; empty when no mesh has them (then every triangle is white). See
    /// [`Scene::vertex_color`].
    pub vertex_colors: Vec<[Vec3; 3]>,
    /// The second set of texture coordinates (glTF `TEXCOORD_1`) per triangle, for textures
    /// whose `texCoord` is 1; empty when no texture reads that set. Triangles without the set
    /// repeat set 0. See [`Scene::tex_coords`].
    pub uv1: Vec<[Vec2; 3]>,
    /// Tangents with handedness in w per triangle (glTF `TANGENT`), for normal maps; empty when
    /// no mesh has them, which is most scenes (each row is 48 bytes a triangle). See
    /// [`Scene::tangents`].
    pub tangents: Vec<[Vec4; 3]>,
}

/// The attributes of a triangle that live in the [`Scene`]'s side tables (tables that exist only
/// once some triangle has the attribute), for [`Scene::push_triangle_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TriangleExtras {
    /// Linear vertex colours (None: white).
    pub colors: Option<[Vec3; 3]>,
    /// Texture coordinates of set 1 (None: the triangle's set 0).
    pub uv1: Option<[Vec2; 3]>,
    /// Tangents with handedness in w (None: derived from the texture coordinates when needed).
    pub tangents: Option<[Vec4; 3]>,
}

/// Appends `value` (or `default` when None) to a side table of `len - 1` earlier rows, creating
/// the table filled with `fill(row)` the first time a value comes.
fn push_side<T: Copy>(table: &mut Vec<T>, len: usize, value: Option<T>, fill: impl Fn(usize) -> T, default: T) {
    if value.is_some() && table.is_empty() {
        *table = (0..len - 1).map(&fill).collect();
    }
    if value.is_some() || !table.is_empty() {
        table.push(value.unwrap_or(default));
    }
}

impl Scene {
    /// Adds a triangle after validation and returns whether it was kept. Triangles with non-finite
    /// positions or zero area are counted and dropped; missing or broken normals become the flat
    /// normal and non-finite texture coordinates zero.
    pub fn push_triangle(&mut self, mut t: Triangle) -> bool {
        if !t.p.iter().all(|p| p.is_finite()) {
            self.skipped_nonfinite += 1;
            return false;
        }
        let c = t.cross();
        let len2 = c.length_squared();
        if !(len2 > 0.0 && len2.is_finite()) {
            self.skipped_degenerate += 1;
            return false;
        }
        let flat = c / len2.sqrt();
        for n in &mut t.n {
            let l = n.length();
            *n = if l.is_finite() && l > 1e-12 { *n / l } else { flat };
        }
        for uv in &mut t.uv {
            if !uv.is_finite() {
                *uv = Vec2::ZERO;
            }
        }
        self.triangles.push(t);
        true
    }

    /// [`Scene::push_triangle`] with the triangle's side-table attributes. Colours are kept only
    /// once some triangle has them (non-finite or negative values become 0), and likewise set 1
    /// of the texture coordinates (non-finite values become 0) and tangents (non-finite ones
    /// become all zero, which means "derive them").
    pub fn push_triangle_with(&mut self, t: Triangle, extras: TriangleExtras) -> bool {
        if !self.push_triangle(t) {
            return false;
        }
        let len = self.triangles.len();
        let clean = |c: Vec3| if c.is_finite() { c.max(Vec3::ZERO) } else { Vec3::ZERO };
        push_side(
            &mut self.vertex_colors,
            len,
            extras.colors.map(|c| c.map(clean)),
            |_| [Vec3::ONE; 3],
            [Vec3::ONE; 3],
        );
        let finite = |uv: Vec2| if uv.is_finite() { uv } else { Vec2::ZERO };
        let own = self.triangles[len - 1].uv;
        let triangles = &self.triangles;
        push_side(&mut self.uv1, len, extras.uv1.map(|u| u.map(finite)), |i| triangles[i].uv, own);
        let tangents =
            extras.tangents.filter(|t| t.iter().all(|v| v.is_finite()) && t.iter().any(|v| *v != Vec4::ZERO));
        push_side(&mut self.tangents, len, tangents, |_| [Vec4::ZERO; 3], [Vec4::ZERO; 3]);
        true
    }

    /// The tangents of triangle `tri` (all zero where the file gave none).
    #[inline]
    pub fn tangents(&self, tri: u32) -> [Vec4; 3] {
        self.tangents.get(tri as usize).copied().unwrap_or([Vec4::ZERO; 3])
    }

    /// The vertex colour of triangle `tri` at barycentrics `b` (white without colours).
    #[inline]
    pub fn vertex_color(&self, tri: u32, b: Vec3) -> Vec3 {
        match self.vertex_colors.get(tri as usize) {
            Some(c) => c[0] * b.x + c[1] * b.y + c[2] * b.z,
            None => Vec3::ONE,
        }
    }

    /// Both sets of texture coordinates of triangle `tri` at barycentrics `b` (set 1 repeats set
    /// 0 where the scene has no second set).
    #[inline]
    pub fn tex_coords(&self, tri: u32, b: Vec3) -> TexCoords {
        let uv = self.triangles[tri as usize].uv;
        self.tex_coords_from(tri, uv[0] * b.x + uv[1] * b.y + uv[2] * b.z, b)
    }

    /// The per-vertex texture coordinates of set `set` (0 or 1) of triangle `tri` (set 1
    /// repeats set 0 where the scene has no second set).
    #[inline]
    pub fn uv_set(&self, tri: u32, set: u8) -> [Vec2; 3] {
        match (set, self.uv1.get(tri as usize)) {
            (1, Some(u)) => *u,
            _ => self.triangles[tri as usize].uv,
        }
    }

    /// [`Scene::tex_coords`] for a caller that has set 0 at `b` already (`uv0`).
    #[inline]
    pub fn tex_coords_from(&self, tri: u32, uv0: Vec2, b: Vec3) -> TexCoords {
        match self.uv1.get(tri as usize) {
            Some(u) => TexCoords([uv0, u[0] * b.x + u[1] * b.y + u[2] * b.z]),
            None => TexCoords([uv0, uv0]),
        }
    }

    /// The texture-coordinate steps of both sets along barycentric steps `steps` on triangle
    /// `tri` (a pixel footprint's edges, for the texture filters).
    #[inline]
    pub fn tex_coord_steps(&self, tri: u32, steps: &[Vec3; 2]) -> [TexCoords; 2] {
        let uv = self.triangles[tri as usize].uv;
        let step = |u: &[Vec2; 3], d: Vec3| u[0] * d.x + u[1] * d.y + u[2] * d.z;
        steps.map(|d| {
            let s0 = step(&uv, d);
            TexCoords([s0, self.uv1.get(tri as usize).map_or(s0, |u| step(u, d))])
        })
    }

    /// Refuses a file `path` with NaN/Inf vertex positions and records the degenerate triangles
    /// it dropped as a warning; importers call this once at the end.
    pub(crate) fn finish_load(&mut self, path: &Path) -> Result<(), SceneError> {
        if self.skipped_nonfinite > 0 {
            return Err(SceneError::new(
                path,
                match self.skipped_nonfinite {
                    1 => "a triangle has a NaN or infinite vertex position".to_string(),
                    n => format!("{n} triangles have NaN or infinite vertex positions"),
                },
            ));
        }
        if self.skipped_degenerate > 0 {
            self.warnings.push(format!("skipped {} degenerate (zero-area) triangles", self.skipped_degenerate));
        }
        if self.materials.is_empty() {
            self.materials.push(Material::default());
        }
        Ok(())
    }

    /// Bytes held on the heap by triangles, side tables, materials and textures (with mips).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.triangles.as_slice())
            + size_of_val(self.vertex_colors.as_slice())
            + size_of_val(self.uv1.as_slice())
            + size_of_val(self.tangents.as_slice())
            + size_of_val(self.materials.as_slice())
            + self.textures.iter().map(|t| t.heap_bytes()).sum::<usize>()
    }

    /// Bounds of all triangles.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.triangles {
            for p in t.p {
                b.grow(p);
            }
        }
        b
    }

    /// A warning when the geometry lies so far from the origin, for its size, that `f32`
    /// positions cannot hold it: the spacing of `f32` values at the farthest coordinate is
    /// over 1/10000 of the scene's extent (1e4 from the origin for a box of 2 units).
    /// Intersections then err by that much, and at worst whole objects collapse.
    pub fn precision_warning(&self) -> Option<String> {
        let b = self.bounds();
        let extent = (b.max - b.min).max_element();
        let far = b.min.abs().max(b.max.abs()).max_element();
        if !(extent > 0.0 && far.is_finite()) {
            return None;
        }
        // Spacing of f32 values at `far`: 2^(exponent − 23).
        let step = f32::from_bits(far.to_bits() & 0x7f80_0000) * f32::EPSILON;
        (step > extent * 1e-4).then(|| {
            format!(
                "geometry lies up to {far:.3e} from the origin, where positions are {step:.1e} apart \
                 ({:.2}% of the scene's {extent:.3e} extent); move the scene nearer the origin",
                100.0 * step / extent
            )
        })
    }

    /// Number of triangles whose material emits.
    pub fn emissive_triangle_count(&self) -> usize {
        self.triangles.iter().filter(|t| self.materials[t.material as usize].is_emissive()).count()
    }

    /// A copy with every position, camera and light moved by `p' = p·scale + offset`.
    /// Radiometric quantities are unchanged, so the image must be the same: a test of scale
    /// robustness. Punctual light intensities are scaled by scale² to keep irradiance fixed.
    pub fn transformed(&self, scale: f32, offset: Vec3) -> Scene {
        let mut s = self.clone();
        for t in &mut s.triangles {
            for p in &mut t.p {
                *p = *p * scale + offset;
            }
        }
        s.cameras = s.cameras.iter().map(|c| c.scaled(scale, offset)).collect();
        for l in &mut s.lights {
            match l {
                Light::Point { position, intensity } => {
                    *position = *position * scale + offset;
                    *intensity *= scale * scale;
                }
                Light::Spot { position, intensity, .. } => {
                    *position = *position * scale + offset;
                    *intensity *= scale * scale;
                }
                Light::Directional { .. } => {}
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [Vec3; 3]) -> Triangle {
        Triangle { p, n: [Vec3::ZERO; 3], uv: [Vec2::ZERO; 3], material: 0 }
    }

    #[test]
    fn bad_triangles_are_counted_and_dropped() {
        let mut s = Scene::default();
        assert!(s.push_triangle(tri([Vec3::ZERO, Vec3::X, Vec3::Y])));
        assert!(!s.push_triangle(tri([Vec3::ZERO, Vec3::X, Vec3::X * 2.0])));
        s.finish_load(Path::new("s.obj")).unwrap();
        assert_eq!(s.triangles[0].n[0], Vec3::Z, "missing normals become flat normals");
        assert_eq!(s.warnings, ["skipped 1 degenerate (zero-area) triangles"]);
        // A NaN position is refused by the triangle and fails the file's load.
        assert!(!s.push_triangle(tri([Vec3::ZERO, Vec3::splat(f32::NAN), Vec3::Y])));
        assert!(!s.push_triangle(tri([Vec3::ZERO, Vec3::X, Vec3::splat(f32::INFINITY)])));
        assert_eq!((s.triangles.len(), s.skipped_degenerate, s.skipped_nonfinite), (1, 1, 2));
        let e = s.finish_load(Path::new("s.obj")).unwrap_err();
        assert_eq!(e.to_string(), "s.obj: 2 triangles have NaN or infinite vertex positions");
    }

    /// Tangents live in a side table that exists only once some triangle brings them: a scene
    /// without them pays nothing per triangle, and rows before the first one read zero.
    #[test]
    fn tangents_are_a_side_table_kept_only_when_given() {
        let mut s = Scene::default();
        let t = || tri([Vec3::ZERO, Vec3::X, Vec3::Y]);
        let none = TriangleExtras::default();
        assert!(s.push_triangle_with(t(), none));
        assert!(s.tangents.is_empty(), "no table without tangents");
        let given = [Vec4::new(1.0, 0.0, 0.0, -1.0); 3];
        assert!(s.push_triangle_with(t(), TriangleExtras { tangents: Some(given), ..none }));
        let broken = [Vec4::splat(f32::NAN); 3];
        assert!(s.push_triangle_with(t(), TriangleExtras { tangents: Some(broken), ..none }));
        assert_eq!(s.tangents.len(), 3);
        assert_eq!((s.tangents(0), s.tangents(1), s.tangents(2)), ([Vec4::ZERO; 3], given, [Vec4::ZERO; 3]));
        assert_eq!(s.heap_bytes(), 3 * std::mem::size_of::<Triangle>() + 3 * 48);
    }
}
