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
    /// A point light restricted to a cone, with Blender's smooth edge ([`Light::spot`]).
    Spot {
        /// World position.
        position: Vec3,
        /// Unit direction the spot points to.
        direction: Vec3,
        /// Radiant intensity on the axis, per channel.
        intensity: Vec3,
        /// Cosine of the outer cone angle (zero outside).
        cos_outer: f32,
        /// Width of the smooth edge in cosine, inward from `cos_outer` (0: a hard edge).
        smooth: f32,
    },
    /// Parallel light from infinitely far away.
    Directional {
        /// Unit direction the light travels in.
        direction: Vec3,
        /// Irradiance on a surface facing the light, per channel.
        irradiance: Vec3,
    },
}

impl Light {
    /// A spot light with glTF's cone angles (radians from the axis), its edge as Blender draws
    /// it. Blender's exporter writes spot size S and blend b as outer = S/2 and
    /// inner = outer·(1 − b); Cycles fades a spot by smoothstep((cosθ − cos outer) / smooth)
    /// with smooth = (1 − cos outer)·b. So b = 1 − inner/outer, and a file from Blender renders
    /// with the cone its author saw. (glTF leaves the falloff to the renderer.)
    pub fn spot(position: Vec3, direction: Vec3, intensity: Vec3, inner: f32, outer: f32) -> Light {
        let outer = if outer.is_finite() { outer.clamp(1e-4, std::f32::consts::FRAC_PI_2) } else { 0.785 };
        let inner = if inner.is_finite() { inner.clamp(0.0, outer) } else { 0.0 };
        let blend = 1.0 - inner / outer;
        let cos_outer = outer.cos();
        Light::Spot { position, direction, intensity, cos_outer, smooth: (1.0 - cos_outer) * blend }
    }

    /// The spot's falloff at cosine `cos_axis` from its axis: 0 outside the cone, 1 inside the
    /// smooth edge, smoothstep across it. 1 for other lights.
    #[inline]
    pub fn cone_falloff(&self, cos_axis: f32) -> f32 {
        match *self {
            Light::Spot { cos_outer, smooth, .. } => {
                if !(cos_axis > cos_outer) {
                    0.0
                } else if smooth <= 0.0 {
                    1.0
                } else {
                    // smoothstep(0, 1, t) = t²(3 − 2t).
                    let t = ((cos_axis - cos_outer) / smooth).min(1.0);
                    t * t * (3.0 - 2.0 * t)
                }
            }
            Light::Point { .. } | Light::Directional { .. } => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spot_cone_is_blenders() {
        // Blender: spot size 60°, blend 0.25 → outer 30°, inner 22.5°.
        let (outer, inner) = (30f32.to_radians(), 22.5f32.to_radians());
        let l = Light::spot(Vec3::ZERO, Vec3::NEG_Z, Vec3::ONE, inner, outer);
        let cos_outer = outer.cos();
        let smooth = (1.0 - cos_outer) * 0.25;
        assert_eq!(l.cone_falloff(31f32.to_radians().cos()), 0.0);
        assert_eq!(l.cone_falloff(1.0), 1.0);
        assert_eq!(l.cone_falloff(cos_outer + smooth), 1.0);
        assert!((l.cone_falloff(cos_outer + 0.5 * smooth) - 0.5).abs() < 1e-5);
        assert!((l.cone_falloff(cos_outer + 0.25 * smooth) - 0.15625).abs() < 1e-5);
        // Equal angles: a hard edge; bad angles stay finite.
        let hard = Light::spot(Vec3::ZERO, Vec3::NEG_Z, Vec3::ONE, outer, outer);
        assert_eq!(hard.cone_falloff(cos_outer + 1e-4), 1.0);
        let odd = Light::spot(Vec3::ZERO, Vec3::NEG_Z, Vec3::ONE, f32::NAN, 9.0);
        assert!(odd.cone_falloff(0.5).is_finite());
    }
}
