//! Pinhole camera. The film records radiance arriving along each pixel's rays (no cos⁴
//! fall-off), as Mitsuba's `perspective` sensor does.

use crate::geometry::Ray;
use crate::math::Vec3;

/// A pinhole camera; image x grows to the right, y downwards, (0, 0) at the top-left corner.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Eye position, scene units.
    pub position: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_x: f64,
    tan_half_y: f64,
}

impl Camera {
    /// Camera at `position` looking at `look_at`, with `up` hint, vertical field of view
    /// `fov_y` in degrees and image aspect `width/height`. Callers validate that `up` is not
    /// parallel to the view direction.
    pub fn new(position: Vec3, look_at: Vec3, up: Vec3, fov_y_degrees: f64, aspect: f64) -> Self {
        let forward = (look_at - position).normalize();
        // right = forward × up: for the Cornell camera (forward +z, up +y) this is −x, so
        // +x appears on the left of the image, as the Cornell data specify.
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        let tan_half_y = (fov_y_degrees.to_radians() * 0.5).tan();
        Camera {
            position,
            forward,
            right,
            up,
            tan_half_x: tan_half_y * aspect,
            tan_half_y,
        }
    }

    /// The ray through film position (x, y) in pixels of a `width`×`height` image.
    #[inline]
    pub fn ray(&self, x: f64, y: f64, width: usize, height: usize) -> Ray {
        let sx = (2.0 * x / width as f64 - 1.0) * self.tan_half_x;
        let sy = (1.0 - 2.0 * y / height as f64) * self.tan_half_y;
        let d = (self.forward + self.right * sx + self.up * sy).normalize();
        Ray {
            o: self.position,
            d,
        }
    }
}

/// Vertical field of view in degrees from a focal length and film height (same units).
pub fn fov_from_film(focal_length: f64, film_height: f64) -> f64 {
    2.0 * (0.5 * film_height / focal_length).atan().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_camera_geometry() {
        let fov = fov_from_film(0.035, 0.025);
        assert!((fov - 39.3077).abs() < 1e-4, "{fov}");
        let c = Camera::new(
            Vec3::new(278.0, 273.0, -800.0),
            Vec3::new(278.0, 273.0, 0.0),
            Vec3::Y,
            fov,
            1.0,
        );
        let centre = c.ray(128.0, 128.0, 256, 256);
        assert!((centre.d - Vec3::Z).length() < 1e-12);
        // left edge of the image looks towards +x
        assert!(c.ray(0.0, 128.0, 256, 256).d.x > 0.0);
        // top edge looks up
        assert!(c.ray(128.0, 0.0, 256, 256).d.y > 0.0);
    }
}
