//! Benchmark scenes rtd was not tuned on, generated rather than shipped: a broader set of
//! families a production scene is made of (thin strands, dense fine textures, many small
//! lights, a large instanced mesh, a glossy interior, large flat walls), and the scenes of
//! `rtd bench scaling`, which grow one cost axis at a time. Every scene is a pure function of
//! its name and parameters, written as glTF by the dataset's writer.

use std::f32::consts::TAU;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rtd_train::scenegen::{make_texture, GenCamera, GenMaterial, GenScene, Mesh, Pattern};

use crate::BenchError;

/// A family of the broader benchmark set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    /// 120 thin strands before fine stripes and faint lines: the guide pass's worst case.
    Strands,
    /// Walls and floor covered in 1024² textures of fine checkers and noise, repeated.
    FineTextures,
    /// 1,024 small coloured emitters and no other light, on the ceiling of a 10 m room.
    ManySmallLights,
    /// 1,024 small coloured emitters spread over the ceiling of an 80 m hall, where most are
    /// far from any one point.
    LightHall,
    /// One 131k-triangle displaced mesh placed 16 times (2.1 million triangles once flattened).
    InstancedMesh,
    /// Glossy walls, floor and objects (roughness 0.05–0.3).
    GlossyInterior,
    /// A large room of flat walls lit only indirectly, where denoisers leave blotches.
    FlatWalls,
}

impl Family {
    /// Every family, in report order.
    pub const ALL: [Family; 7] = [
        Family::Strands,
        Family::FineTextures,
        Family::ManySmallLights,
        Family::LightHall,
        Family::InstancedMesh,
        Family::GlossyInterior,
        Family::FlatWalls,
    ];

    /// The file name (without extension) the family's scene is written under.
    pub fn name(self) -> &'static str {
        match self {
            Family::Strands => "strands",
            Family::FineTextures => "fine-textures",
            Family::ManySmallLights => "many-small-lights",
            Family::LightHall => "light-hall",
            Family::InstancedMesh => "instanced-mesh",
            Family::GlossyInterior => "glossy-interior",
            Family::FlatWalls => "flat-walls",
        }
    }

    /// The family's scene.
    pub fn scene(self) -> GenScene {
        let mut rng = ChaCha8Rng::seed_from_u64(self as u64 + 1);
        match self {
            Family::Strands => strands(&mut rng),
            Family::FineTextures => fine_textures(&mut rng),
            Family::ManySmallLights => room_with_lights(&mut rng, 1024, false),
            Family::LightHall => light_hall(&mut rng),
            Family::InstancedMesh => instanced(&mut rng),
            Family::GlossyInterior => glossy(&mut rng),
            Family::FlatWalls => flat_walls(),
        }
    }
}

/// Writes `scene` as `dir/name.gltf` (with its buffer and textures) unless it is there already,
/// and returns the path.
pub fn write_scene(dir: &Path, name: &str, scene: &GenScene) -> Result<PathBuf, BenchError> {
    let path = dir.join(format!("{name}.gltf"));
    if !path.exists() {
        scene.write(dir, name).map_err(|e| BenchError::msg(dir, e.to_string()))?;
    }
    Ok(path)
}

/// Writes every family's scene into `dir`; returns their paths.
pub fn write_families(dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
    Family::ALL.iter().map(|f| write_scene(dir, f.name(), &f.scene())).collect()
}

/// Adds a material, returning its index.
fn material(scene: &mut GenScene, m: GenMaterial) -> usize {
    scene.materials.push(m);
    scene.materials.len() - 1
}

/// An emitter of radiance `colour` × `strength`.
fn emitter(colour: Vec3, strength: f32) -> GenMaterial {
    GenMaterial { emissive: colour, emissive_strength: strength, ..GenMaterial::diffuse(Vec3::ZERO) }
}

/// A glossy dielectric or metal.
fn glossy_material(colour: Vec3, roughness: f32, metallic: f32) -> GenMaterial {
    GenMaterial { roughness, metallic, ..GenMaterial::diffuse(colour) }
}

/// A 10 × 4 × 10 room seen from near one wall, with diffuse surfaces of `walls`; returns the
/// scene with one camera.
fn room(walls: GenMaterial) -> GenScene {
    let mut s = GenScene::default();
    let m = material(&mut s, walls);
    s.objects.push((Mesh::cuboid(Vec3::new(0.0, 2.0, 0.0), Vec3::new(5.0, 2.0, 5.0), Mat3::IDENTITY, true, 4.0), m));
    s.cameras.push(GenCamera { from: Vec3::new(0.0, 1.8, 4.6), at: Vec3::new(0.0, 1.2, 0.0), yfov_degrees: 60.0 });
    s
}

/// A room with a ceiling panel light of the given size.
pub fn lit_room(panel: f32) -> GenScene {
    let mut s = room(GenMaterial::diffuse(Vec3::splat(0.7)));
    let light = material(&mut s, emitter(Vec3::ONE, 8.0));
    let (y, h) = (3.99, panel * 0.5);
    s.objects.push((
        Mesh::quad(Vec3::new(-h, y, -h), Vec3::new(h, y, -h), Vec3::new(h, y, h), Vec3::new(-h, y, h), 1.0),
        light,
    ));
    s
}

/// A room lit by `count` small emitters spread over the ceiling (and, with `walls`, the side
/// walls), of random colours and a total power independent of the count.
pub fn room_with_lights(rng: &mut ChaCha8Rng, count: usize, walls: bool) -> GenScene {
    let mut s = room(GenMaterial::diffuse(Vec3::splat(0.7)));
    let side = (count as f32).sqrt().ceil() as usize;
    // Each light's area falls as 1/count, so a constant radiance keeps the power constant.
    let h = 4.0 / side as f32 * 0.2;
    for i in 0..count {
        let colour = Vec3::new(rng.random_range(0.3..1.0), rng.random_range(0.3..1.0), rng.random_range(0.3..1.0));
        let m = material(&mut s, emitter(colour, 40.0));
        let (gx, gz) = ((i % side) as f32 + 0.5, (i / side) as f32 + 0.5);
        let (x, z) = (-4.0 + 8.0 * gx / side as f32, -4.0 + 8.0 * gz / side as f32);
        let quad = if walls && i % 3 == 0 {
            let y = 0.4 + 3.2 * gz / side as f32;
            Mesh::quad(
                Vec3::new(-4.99, y - h, x - h),
                Vec3::new(-4.99, y - h, x + h),
                Vec3::new(-4.99, y + h, x + h),
                Vec3::new(-4.99, y + h, x - h),
                1.0,
            )
        } else {
            let y = 3.99;
            Mesh::quad(
                Vec3::new(x - h, y, z - h),
                Vec3::new(x + h, y, z - h),
                Vec3::new(x + h, y, z + h),
                Vec3::new(x - h, y, z + h),
                1.0,
            )
        };
        s.objects.push((quad, m));
    }
    s
}

fn light_hall(rng: &mut ChaCha8Rng) -> GenScene {
    let mut s = GenScene::default();
    let m = material(&mut s, GenMaterial::diffuse(Vec3::splat(0.7)));
    s.objects.push((Mesh::cuboid(Vec3::new(0.0, 2.0, 0.0), Vec3::new(40.0, 2.0, 40.0), Mat3::IDENTITY, true, 4.0), m));
    s.cameras.push(GenCamera { from: Vec3::new(0.0, 1.8, 30.0), at: Vec3::new(0.0, 1.0, 20.0), yfov_degrees: 60.0 });
    let (y, h) = (3.99, 0.1);
    for i in 0..1024 {
        let colour = Vec3::new(rng.random_range(0.3..1.0), rng.random_range(0.3..1.0), rng.random_range(0.3..1.0));
        let e = material(&mut s, emitter(colour, 40.0));
        let (x, z) = (-38.0 + 76.0 * ((i % 32) as f32 + 0.5) / 32.0, -38.0 + 76.0 * ((i / 32) as f32 + 0.5) / 32.0);
        let quad = Mesh::quad(
            Vec3::new(x - h, y, z - h),
            Vec3::new(x + h, y, z - h),
            Vec3::new(x + h, y, z + h),
            Vec3::new(x - h, y, z + h),
            1.0,
        );
        s.objects.push((quad, e));
    }
    s
}

fn strands(rng: &mut ChaCha8Rng) -> GenScene {
    let mut s = lit_room(2.0);
    let stripes = make_texture(Pattern::Stripes, 512, rng);
    let faint = make_texture(Pattern::FaintLines, 512, rng);
    s.textures.extend([stripes, faint]);
    let back = material(&mut s, GenMaterial { texture: Some(0), ..GenMaterial::diffuse(Vec3::ONE) });
    let floor = material(&mut s, GenMaterial { texture: Some(1), ..GenMaterial::diffuse(Vec3::ONE) });
    s.objects.push((
        Mesh::quad(
            Vec3::new(-5.0, 0.0, -4.98),
            Vec3::new(5.0, 0.0, -4.98),
            Vec3::new(5.0, 4.0, -4.98),
            Vec3::new(-5.0, 4.0, -4.98),
            6.0,
        ),
        back,
    ));
    s.objects.push((
        Mesh::quad(
            Vec3::new(-5.0, 0.01, 5.0),
            Vec3::new(5.0, 0.01, 5.0),
            Vec3::new(5.0, 0.01, -5.0),
            Vec3::new(-5.0, 0.01, -5.0),
            8.0,
        ),
        floor,
    ));
    let hair = material(&mut s, glossy_material(Vec3::new(0.35, 0.2, 0.1), 0.35, 0.0));
    let mut strands = Mesh::default();
    for _ in 0..120 {
        let base = Vec3::new(rng.random_range(-2.5..2.5), 0.0, rng.random_range(-2.5..1.0));
        let lean = Vec3::new(rng.random_range(-0.4..0.4), rng.random_range(1.5..3.2), rng.random_range(-0.4..0.4));
        strands.append(&Mesh::cylinder(base, lean, 0.006, 4));
    }
    s.objects.push((strands, hair));
    s
}

fn fine_textures(rng: &mut ChaCha8Rng) -> GenScene {
    let mut s = lit_room(2.5);
    for pattern in [Pattern::FineCheckers, Pattern::Noise, Pattern::FaintLines] {
        s.textures.push(make_texture(pattern, 1024, rng));
    }
    let textured: Vec<usize> =
        (0..3).map(|t| material(&mut s, GenMaterial { texture: Some(t), ..GenMaterial::diffuse(Vec3::ONE) })).collect();
    let y0 = 0.01;
    s.objects.push((
        Mesh::quad(
            Vec3::new(-5.0, y0, 5.0),
            Vec3::new(5.0, y0, 5.0),
            Vec3::new(5.0, y0, -5.0),
            Vec3::new(-5.0, y0, -5.0),
            12.0,
        ),
        textured[0],
    ));
    s.objects.push((
        Mesh::quad(
            Vec3::new(-5.0, 0.0, -4.98),
            Vec3::new(5.0, 0.0, -4.98),
            Vec3::new(5.0, 4.0, -4.98),
            Vec3::new(-5.0, 4.0, -4.98),
            8.0,
        ),
        textured[1],
    ));
    s.objects.push((
        Mesh::cuboid(Vec3::new(1.2, 0.6, -1.0), Vec3::splat(0.6), Mat3::from_rotation_y(0.5), false, 3.0),
        textured[2],
    ));
    s
}

fn instanced(rng: &mut ChaCha8Rng) -> GenScene {
    let mut s = lit_room(3.0);
    let m = material(&mut s, glossy_material(Vec3::new(0.6, 0.5, 0.4), 0.5, 0.0));
    let phase = rng.random_range(0.0..TAU);
    // 181 segments: 181 × 362 quads, about 131k triangles after the degenerate poles go.
    let blob = Mesh::sphere(Vec3::new(-3.0, 0.45, -3.0), 0.4, 181, &|d: Vec3| {
        0.08 * (7.0 * d.x + phase).sin() * (5.0 * d.y).cos() * (6.0 * d.z).sin()
    });
    s.objects.push((blob, m));
    for k in 1..16 {
        s.instances.push((s.objects.len() - 1, Vec3::new((k % 4) as f32 * 2.0, 0.0, (k / 4) as f32 * 2.0)));
    }
    s
}

fn glossy(rng: &mut ChaCha8Rng) -> GenScene {
    let mut s = lit_room(1.5);
    let floor = material(&mut s, glossy_material(Vec3::new(0.5, 0.45, 0.4), 0.08, 0.0));
    let wall = material(&mut s, glossy_material(Vec3::new(0.7, 0.75, 0.8), 0.2, 1.0));
    s.objects.push((
        Mesh::quad(
            Vec3::new(-5.0, 0.01, 5.0),
            Vec3::new(5.0, 0.01, 5.0),
            Vec3::new(5.0, 0.01, -5.0),
            Vec3::new(-5.0, 0.01, -5.0),
            1.0,
        ),
        floor,
    ));
    s.objects.push((
        Mesh::quad(
            Vec3::new(-4.98, 0.0, 5.0),
            Vec3::new(-4.98, 0.0, -5.0),
            Vec3::new(-4.98, 4.0, -5.0),
            Vec3::new(-4.98, 4.0, 5.0),
            1.0,
        ),
        wall,
    ));
    for i in 0..6 {
        let c = Vec3::new(rng.random_range(0.2..0.9), rng.random_range(0.2..0.9), rng.random_range(0.2..0.9));
        let m = material(&mut s, glossy_material(c, rng.random_range(0.05..0.3), (i % 2) as f32));
        let at = Vec3::new(-2.5 + i as f32, 0.45, rng.random_range(-2.0..0.5));
        s.objects.push((Mesh::sphere(at, 0.45, 48, &|_| 0.0), m));
    }
    s
}

fn flat_walls() -> GenScene {
    // The light faces the ceiling from behind a baffle, so every wall is lit indirectly.
    let mut s = room(GenMaterial::diffuse(Vec3::new(0.75, 0.72, 0.68)));
    let light = material(&mut s, emitter(Vec3::ONE, 30.0));
    let baffle = material(&mut s, GenMaterial::diffuse(Vec3::splat(0.2)));
    let y = 3.0;
    s.objects.push((
        Mesh::quad(
            Vec3::new(-1.0, y, 1.0),
            Vec3::new(-1.0, y, -1.0),
            Vec3::new(1.0, y, -1.0),
            Vec3::new(1.0, y, 1.0),
            1.0,
        ),
        light,
    ));
    s.objects.push((
        Mesh::cuboid(Vec3::new(0.0, y - 0.05, 0.0), Vec3::new(1.2, 0.04, 1.2), Mat3::IDENTITY, false, 1.0),
        baffle,
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_loads_with_its_camera_and_light() {
        let dir = tempfile::tempdir().unwrap();
        for (family, path) in Family::ALL.iter().zip(write_families(dir.path()).unwrap()) {
            let scene = rtd_scene::load_scene(&path).unwrap();
            assert_eq!(scene.cameras.len(), 1, "{family:?}");
            assert!(scene.emissive_triangle_count() > 0, "{family:?} has no light");
            let tris = scene.triangles.len();
            match family {
                Family::InstancedMesh => assert!(tris > 1_000_000, "{tris}"),
                Family::ManySmallLights | Family::LightHall => assert_eq!(scene.emissive_triangle_count(), 2048),
                Family::Strands => assert!((1000..5000).contains(&tris), "{tris}"),
                _ => assert!(tris > 12, "{tris}"),
            }
        }
    }
}
