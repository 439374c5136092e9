use glam::Vec3;

/// A punctual (delta) light from `KHR_lights_punctual`.
///
/// Units: rtd uses the extension's photometric numbers directly as its radiometric scene
/// units, with no 683 lm/W factor. A point or spot light of intensity I (candela) gives
/// irradiance I/d² at distance d; a directional light of intensity E (lux) gives irradiance E.
/// Emissive surfaces emit radiance emissive × emissive strength (nits) in the same units,
/// so a white Lambertian surface under E = π has radiance 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// Emits intensity `intensity` (colour × candela) equally in all directions.
    Point {
        /// World position.
        position: Vec3,
        /// Radiant intensity per channel.
        intensity: Vec3,
    },
    /// A point light restricted to a cone with a smooth falloff between the cone angles.
    Spot {
        /// World position.
        position: Vec3,
        /// Unit direction the spot points to.
        direction: Vec3,
        /// Radiant intensity on the axis, per channel.
        intensity: Vec3,
        /// Cosine of the inner cone angle (full intensity inside).
        cos_inner: f32,
        /// Cosine of the outer cone angle (zero outside).
        cos_outer: f32,
    },
    /// Parallel light from infinitely far away.
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light, per channel.
        irradiance: Vec3,
    },
}
