use glam::Vec3;

/// Luminous efficacy the glTF specification converts light units by: `KHR_lights_punctual`
/// intensities are photometric (candela, lux), and 683 lm make one watt. Blender's exporter writes
/// a P-watt point light as P/(4π) × 683 cd and an S W/m² sun as S × 683 lux.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A punctual (delta) light from `KHR_lights_punctual`, in radiometric units.
///
/// Units: the importer divides the extension's photometric intensities by [`LUMENS_PER_WATT`].
/// A point or spot light of I candela has radiant intensity I/683 W/sr, so irradiance
/// I/(683 d²) at distance d; a directional light of E lux gives irradiance E/683 W/m². A
/// P-watt Blender point light therefore arrives as P/(4π) W/sr, as Cycles emits it. Emissive
/// surfaces emit radiance emissive × emissive strength, unscaled, in the same units, so a white
/// Lambertian surface under irradiance π has radiance 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// Emits radiant intensity `intensity` (colour × candela ÷ 683, W/sr) equally in all
    /// directions.
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
