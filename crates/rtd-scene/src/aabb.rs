use glam::Vec3;

/// An axis-aligned bounding box, grown point by point from [`Aabb::EMPTY`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (min = +∞, max = −∞).
    pub const EMPTY: Aabb = Aabb { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    /// The centre point.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// The box's extent along each axis, max − min.
    pub fn diagonal(&self) -> Vec3 {
        self.max - self.min
    }
    /// True if no point was added (min > max).
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
}
