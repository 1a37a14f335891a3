//! A ray `o + t·d`.

use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

impl Ray {
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Ray { o, d }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.o + t * self.d
    }
}
