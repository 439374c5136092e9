//! `rtd datagen`'s procedural scene generator: rooms, half-open rooms and open ground planes
//! filled with random shapes, materials, procedural textures, area lights and cameras. The
//! scene is a pure function of its seed.

mod gltf_writer;
mod mesh;
mod textures;

pub use gltf_writer::{GenCamera, GenMaterial, GenScene};
pub use mesh::Mesh;
pub use textures::{make_texture, Pattern};

use glam::{Mat3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f32::consts::TAU;

/// The overall arrangement of a generated scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Layout {
    /// A closed box room lit from inside.
    ClosedRoom,
    /// Floor, back and side walls under a sky dome.
    HalfOpenRoom,
    /// An open ground plane under a sky dome and a sun.
    OpenGround,
}

/// Options for [`generate_scene`].
#[derive(Clone, Debug)]
pub struct SceneGenOptions {
    /// Cameras (views) per scene.
    pub views: usize,
    /// Procedural texture size in pixels.
    pub texture_size: u32,
}

impl Default for SceneGenOptions {
    fn default() -> Self {
        SceneGenOptions { views: 2, texture_size: 256 }
    }
}

/// Random scene builder state.
struct Builder {
    rng: ChaCha8Rng,
    scene: GenScene,
    texture_size: u32,
}

impl Builder {
    fn material(&mut self, m: GenMaterial) -> usize {
        self.scene.materials.push(m);
        self.scene.materials.len() - 1
    }

    fn texture(&mut self) -> usize {
        let p = Pattern::ALL[self.rng.random_range(0..Pattern::ALL.len())];
        let t = make_texture(p, self.texture_size, &mut self.rng);
        self.scene.textures.push(t);
        self.scene.textures.len() - 1
    }

    /// A textured or plain diffuse surface material (walls, floors, panels).
    fn surface_material(&mut self, texture_probability: f32) -> usize {
        let mut m = GenMaterial::diffuse(textures::random_colour(&mut self.rng, 0.1, 0.85));
        if self.rng.random::<f32>() < texture_probability {
            m.base_color = Vec3::ONE;
            m.texture = Some(self.texture());
        }
        if self.rng.random::<f32>() < 0.25 {
            m.roughness = self.rng.random_range(0.1..0.6);
        }
        self.material(m)
    }

    /// An object material: diffuse, glossy dielectric, metal, or smooth or rough glass.
    fn object_material(&mut self) -> usize {
        let r = &mut self.rng;
        let colour = textures::random_colour(r, 0.05, 0.9);
        let kind = r.random_range(0..10);
        let mut m = GenMaterial::diffuse(colour);
        match kind {
            0..=3 => {
                if r.random::<f32>() < 0.5 {
                    m.base_color = Vec3::ONE;
                    m.texture = Some(self.texture());
                }
            }
            4..=5 => m.roughness = 0.02 + 0.98 * r.random::<f32>().powi(2),
            6..=7 => {
                m.metallic = 1.0;
                m.base_color = textures::random_colour(r, 0.5, 0.98);
                m.roughness = 0.02 + 0.6 * r.random::<f32>();
            }
            _ => {
                m.transmission = 1.0;
                m.base_color = Vec3::ONE.lerp(colour, 0.3 * r.random::<f32>());
                m.roughness = if r.random::<f32>() < 0.5 { 0.0 } else { r.random_range(0.05..0.4) };
                m.ior = r.random_range(1.3..1.8);
            }
        }
        self.material(m)
    }

    /// An emissive material of linear colour `c` and strength `s`.
    fn emitter(&mut self, c: Vec3, s: f32) -> usize {
        let mut m = GenMaterial::diffuse(Vec3::ZERO);
        m.emissive = c;
        m.emissive_strength = s;
        self.material(m)
    }

    fn light_colour(&mut self) -> Vec3 {
        if self.rng.random::<f32>() < 0.3 {
            (textures::random_colour(&mut self.rng, 0.2, 1.0) + Vec3::splat(0.1)).min(Vec3::ONE)
        } else {
            Vec3::new(1.0, 0.95, 0.85)
        }
    }

    /// A downward-facing rectangular light of side `size` at `center`, with radiance scaled so
    /// that its power is `power` (W-like units) whatever its size: small lights are intense.
    fn ceiling_light(&mut self, center: Vec3, size: f32, power: f32, baffle: bool) {
        let h = size * 0.5;
        let (a, b, c, d) = (
            center + Vec3::new(-h, 0.0, -h),
            center + Vec3::new(h, 0.0, -h),
            center + Vec3::new(h, 0.0, h),
            center + Vec3::new(-h, 0.0, h),
        );
        let colour = self.light_colour();
        let strength = power / (size * size * std::f32::consts::PI);
        let m = self.emitter(colour, strength);
        // Counter-clockwise seen from below (normal -y).
        self.scene.objects.push((Mesh::quad(a, b, c, d, 1.0), m));
        if baffle {
            // A panel below the light that hides it: everything is lit indirectly.
            let panel = self.surface_material(0.0);
            let hb = h + 0.3;
            let y = center.y - 0.15;
            let mesh =
                Mesh::cuboid(Vec3::new(center.x, y, center.z), Vec3::new(hb, 0.02, hb), Mat3::IDENTITY, false, 1.0);
            self.scene.objects.push((mesh, panel));
        }
    }

    /// A random object standing in the square |x|,|z| < `extent` on the floor y = 0.
    fn object(&mut self, extent: f32) -> Vec3 {
        let r = &mut self.rng;
        let pos = Vec3::new(r.random_range(-extent..extent), 0.0, r.random_range(-extent..extent));
        let s = r.random_range(0.2..0.6);
        let rot = Mat3::from_rotation_y(r.random::<f32>() * TAU);
        let kind = r.random_range(0..8);
        let material = self.object_material();
        let r = &mut self.rng;
        let mesh = match kind {
            0 => Mesh::cuboid(pos + Vec3::Y * s, Vec3::new(s, s, s * r.random_range(0.5..1.5)), rot, false, 1.0),
            1 => Mesh::sphere(pos + Vec3::Y * s, s, 24, &|_| 0.0),
            2 => Mesh::cylinder(pos, Vec3::Y * s * r.random_range(1.0..3.0), s * 0.5, 32),
            3 => {
                let axis = if r.random::<bool>() { Vec3::Y } else { rot * Vec3::X };
                let minor = s * 0.3;
                let lift = if axis == Vec3::Y { minor } else { s + minor };
                Mesh::torus(pos + Vec3::Y * lift, axis, s, minor, 24)
            }
            4 => {
                let (f, a, ph) = (r.random_range(2.0..8.0), r.random_range(0.05..0.2), r.random::<f32>() * TAU);
                Mesh::sphere(pos + Vec3::Y * s * 1.2, s, 40, &move |d: Vec3| {
                    a * ((f * d.x + ph).sin() * (f * d.y).cos() + (f * d.z).sin() * 0.5)
                })
            }
            5 => {
                // Thin strands: a bundle of slim cylinders leaning at random.
                let mut m = Mesh::default();
                for _ in 0..r.random_range(3..9) {
                    let base = pos + Vec3::new(r.random_range(-s..s), 0.0, r.random_range(-s..s));
                    let axis = Vec3::new(r.random_range(-0.3..0.3), 1.0, r.random_range(-0.3..0.3))
                        * s
                        * r.random_range(2.0..4.0);
                    m.append(&Mesh::cylinder(base, axis, r.random_range(0.004..0.015), 8));
                }
                m
            }
            6 => {
                // A thin panel carrying a high-frequency texture.
                let h = Vec3::new(s * 1.5, s * 1.5, 0.01);
                let panel = self.surface_material(1.0);
                let mesh = Mesh::cuboid(pos + Vec3::Y * h.y, h, rot, false, 1.0);
                self.scene.objects.push((mesh, panel));
                return pos;
            }
            _ => Mesh::cuboid(pos + Vec3::Y * s * 0.5, Vec3::new(s * 1.5, s * 0.5, s * 0.8), rot, false, 2.0),
        };
        self.scene.objects.push((mesh, material));
        pos
    }

    /// A sky dome (inward-facing emissive sphere) of `radius`, sometimes with a sun disc.
    fn sky(&mut self, radius: f32, sun: bool) {
        let sky_colour = Vec3::new(0.5, 0.7, 1.0).lerp(Vec3::ONE, self.rng.random::<f32>());
        let strength = self.rng.random_range(0.3..1.5);
        let m = self.emitter(sky_colour, strength);
        let mut dome = Mesh::sphere(Vec3::ZERO, radius, 16, &|_| 0.0);
        dome.flip();
        self.scene.objects.push((dome, m));
        if sun {
            let dir = Vec3::new(
                self.rng.random_range(-1.0..1.0),
                self.rng.random_range(0.4..1.5),
                self.rng.random_range(-1.0..1.0),
            )
            .normalize();
            let c = dir * radius * 0.9;
            let size = radius * 0.02;
            let (u, v) = (dir.any_orthonormal_vector() * size, dir.cross(dir.any_orthonormal_vector()) * size);
            let strength = self.rng.random_range(2000.0..20000.0);
            let e = self.emitter(Vec3::new(1.0, 0.9, 0.75), strength);
            let mut q = Mesh::quad(c - u - v, c + u - v, c + u + v, c - u + v, 1.0);
            if q.normals[0].dot(dir) > 0.0 {
                q.flip();
            }
            self.scene.objects.push((q, e));
        }
    }
}

impl Mesh {
    /// Turns every face around (winding and normals).
    pub fn flip(&mut self) {
        for t in self.indices.chunks_mut(3) {
            t.swap(1, 2);
        }
        for n in &mut self.normals {
            *n = -*n;
        }
    }
}

/// The room's half width and depth, its height and the lights' total power: drawn first for
/// every layout (an open ground uses them to place its objects and cameras).
#[derive(Clone, Copy)]
struct Room {
    hw: f32,
    hd: f32,
    height: f32,
    power_scale: f32,
}

/// The room cuboid `room` split into its floor (face 3) and the other faces: (rest, floor).
fn split_floor(room: &Mesh) -> (Mesh, Mesh) {
    let (mut rest, mut floor_mesh) = (Mesh::default(), Mesh::default());
    for (f, chunk) in room.indices.chunks(6).enumerate() {
        let mut part = Mesh::default();
        let base = (f * 4) as u32;
        for i in 0..4 {
            let k = (base + i) as usize;
            part.positions.push(room.positions[k]);
            part.normals.push(room.normals[k]);
            part.uvs.push(room.uvs[k]);
        }
        part.indices = chunk.iter().map(|i| i - base).collect();
        if f == 3 {
            floor_mesh.append(&part)
        } else {
            rest.append(&part)
        }
    }
    (rest, floor_mesh)
}

impl Builder {
    /// A closed box room with its own floor material and one to four ceiling lights,
    /// sometimes all behind baffles.
    fn closed_room(&mut self, room: Room) {
        let Room { hw, hd, height, power_scale } = room;
        let walls = self.surface_material(0.4);
        let floor = self.surface_material(0.7);
        let cuboid =
            Mesh::cuboid(Vec3::new(0.0, height * 0.5, 0.0), Vec3::new(hw, height * 0.5, hd), Mat3::IDENTITY, true, 3.0);
        // The floor (face 3 of the cuboid) gets its own material: split it off.
        let (rest, floor_mesh) = split_floor(&cuboid);
        self.scene.objects.push((rest, walls));
        self.scene.objects.push((floor_mesh, floor));
        let n_lights = self.rng.random_range(1..=4);
        let baffled = self.rng.random::<f32>() < 0.25;
        for _ in 0..n_lights {
            let size = if self.rng.random::<f32>() < 0.3 {
                self.rng.random_range(0.05..0.15)
            } else {
                self.rng.random_range(0.4..1.6)
            };
            let c = Vec3::new(
                self.rng.random_range(-hw * 0.7..hw * 0.7),
                height - 0.01,
                self.rng.random_range(-hd * 0.7..hd * 0.7),
            );
            self.ceiling_light(c, size, power_scale / n_lights as f32, baffled);
        }
    }

    /// A floor under a sky dome (with a sun 70% of the time): 12 units a side for
    /// [`Layout::OpenGround`], the room's size with a back and a side wall for
    /// [`Layout::HalfOpenRoom`].
    fn open_layout(&mut self, room: Room, layout: Layout) {
        let Room { hw, hd, .. } = room;
        let floor = self.surface_material(0.8);
        let ext = if layout == Layout::OpenGround { 12.0 } else { hw.max(hd) };
        self.scene.objects.push((
            Mesh::quad(
                Vec3::new(-ext, 0.0, ext),
                Vec3::new(ext, 0.0, ext),
                Vec3::new(ext, 0.0, -ext),
                Vec3::new(-ext, 0.0, -ext),
                ext,
            ),
            floor,
        ));
        if layout == Layout::HalfOpenRoom {
            self.half_open_walls(room);
        }
        let sun = self.rng.random::<f32>() < 0.7;
        self.sky(30.0, sun);
    }

    /// The back and side walls of a half-open room, and half the time a ceiling-height light.
    fn half_open_walls(&mut self, room: Room) {
        let Room { hw, hd, height, power_scale } = room;
        let wall = self.surface_material(0.5);
        self.scene.objects.push((
            Mesh::quad(
                Vec3::new(-hw, 0.0, -hd),
                Vec3::new(hw, 0.0, -hd),
                Vec3::new(hw, height, -hd),
                Vec3::new(-hw, height, -hd),
                2.0,
            ),
            wall,
        ));
        self.scene.objects.push((
            Mesh::quad(
                Vec3::new(-hw, 0.0, hd),
                Vec3::new(-hw, 0.0, -hd),
                Vec3::new(-hw, height, -hd),
                Vec3::new(-hw, height, hd),
                2.0,
            ),
            wall,
        ));
        if self.rng.random::<bool>() {
            let size = self.rng.random_range(0.1..1.0);
            let c = Vec3::new(
                self.rng.random_range(-hw * 0.5..hw * 0.5),
                height * 0.9,
                self.rng.random_range(-hd * 0.5..hd * 0.5),
            );
            self.ceiling_light(c, size, power_scale * 0.5, false);
        }
    }

    /// Three to eight random objects within `extent` of the centre; returns where they stand.
    fn objects(&mut self, extent: f32) -> Vec<Vec3> {
        let mut targets = vec![];
        for _ in 0..self.rng.random_range(3..9) {
            targets.push(self.object(extent));
        }
        targets
    }

    /// `views` cameras, each looking at a point above one of the `targets` from a random
    /// direction and distance, kept inside the room unless the ground is open.
    fn cameras(&mut self, targets: &[Vec3], room: Room, layout: Layout, views: usize) {
        let Room { hw, hd, height, .. } = room;
        for _ in 0..views {
            let t = targets[self.rng.random_range(0..targets.len())] + Vec3::Y * self.rng.random_range(0.1..0.6);
            let ang = self.rng.random::<f32>() * TAU;
            let dist = self.rng.random_range(1.2..(hw.min(hd) * 1.6).max(1.5));
            let mut from = t + Vec3::new(ang.cos() * dist, self.rng.random_range(0.2..1.5), ang.sin() * dist);
            if layout != Layout::OpenGround {
                let (lo, hi) = (Vec3::new(-hw + 0.1, 0.2, -hd + 0.1), Vec3::new(hw - 0.1, height - 0.2, hd - 0.1));
                from = from.clamp(lo, hi);
            }
            let yfov_degrees = self.rng.random_range(30.0..75.0);
            self.scene.cameras.push(GenCamera { from, at: t, yfov_degrees });
        }
    }
}

/// Generates scene number `index` of the dataset seeded by `seed`: the layout and room size,
/// then the layout's surfaces and lights, the objects and the cameras, in that order of random
/// draws.
pub fn generate_scene(seed: u64, index: u64, options: &SceneGenOptions) -> (GenScene, Layout) {
    let mut b = Builder {
        rng: ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index),
        scene: GenScene::default(),
        texture_size: options.texture_size,
    };
    let layout = match b.rng.random_range(0..10) {
        0..=4 => Layout::ClosedRoom,
        5..=7 => Layout::HalfOpenRoom,
        _ => Layout::OpenGround,
    };
    let (hw, hd) = (b.rng.random_range(1.5..3.0f32), b.rng.random_range(1.5..3.0f32));
    let height = b.rng.random_range(2.4..3.5f32);
    let power_scale = b.rng.random_range(20.0..60.0f32);
    let room = Room { hw, hd, height, power_scale };
    match layout {
        Layout::ClosedRoom => b.closed_room(room),
        Layout::HalfOpenRoom | Layout::OpenGround => b.open_layout(room, layout),
    }
    let targets = b.objects(hw.min(hd) * 0.6);
    b.cameras(&targets, room, layout, options.views);
    (b.scene, layout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_scene_and_others_differ() {
        let o = SceneGenOptions { views: 2, texture_size: 32 };
        let (a, la) = generate_scene(7, 3, &o);
        let (b, lb) = generate_scene(7, 3, &o);
        let (c, _) = generate_scene(7, 4, &o);
        assert_eq!(la, lb);
        assert_eq!(a.objects.len(), b.objects.len());
        assert_eq!(a.objects[0].0.positions, b.objects[0].0.positions);
        assert!(a.objects.len() != c.objects.len() || a.objects[0].0.positions != c.objects[0].0.positions);
    }

    #[test]
    fn generated_scenes_load_through_the_gltf_importer() {
        let dir = tempfile::tempdir().unwrap();
        let mut layouts = std::collections::HashSet::new();
        for i in 0..12 {
            let (s, layout) = generate_scene(1, i, &SceneGenOptions { views: 1, texture_size: 16 });
            layouts.insert(format!("{layout:?}"));
            s.write(dir.path(), &format!("s{i}")).unwrap();
            let scene = rtd_scene::load_scene(&dir.path().join(format!("s{i}.gltf"))).unwrap();
            assert_eq!(scene.cameras.len(), 1);
            assert!(scene.emissive_triangle_count() > 0);
            assert_eq!(scene.skipped_nonfinite, 0);
        }
        assert_eq!(layouts.len(), 3, "{layouts:?}");
    }
}
