//! Pinhole camera. The film records radiance arriving along each pixel's rays (no cos⁴
//! fall-off), as Mitsuba's `perspective` sensor does.
//!
//! For light tracing the camera is also an emitter of importance. The film plane sits at
//! distance 1 in front of the eye; pixel j measures the box-filtered mean of radiance over its
//! area A_pix = (2 tan_half_x)(2 tan_half_y)/(width·height) on that plane. With the sensor's
//! cosine written out, I_j = ∫ W_e(ω) L(ω) cos θ dω, and since a plane at distance 1 has
//! dA = dω/cos³θ, the importance is W_e(ω) = 1/(A_pix cos⁴θ) inside pixel j and 0 elsewhere
//! (Veach 1997, PhD thesis, §8.1.1 (sensor response as an importance integral); the cos⁴
//! form is pbrt-v3's `PerspectiveCamera::We`, Pharr, Jakob & Humphreys, PBR 3rd ed., §16.1.1).

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

/// Where a world point appears on the film of a `width`×`height` image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Film x in pixels (0 at the left edge, grows to the right), as in [`Camera::ray`].
    pub x: f64,
    /// Film y in pixels (0 at the top edge, grows downwards), as in [`Camera::ray`].
    pub y: f64,
    /// Unit direction from the eye towards the point (world).
    pub direction: Vec3,
    /// Distance from the eye to the point, scene units.
    pub distance: f64,
    /// cos θ between `direction` and the camera's forward axis (in (0, 1]).
    pub cos_theta: f64,
}

impl Camera {
    /// Projects the world point `p` onto the film of a `width`×`height` image (the inverse of
    /// [`Camera::ray`]); None when `p` is at or behind the eye plane or outside the image.
    pub fn project(&self, p: Vec3, width: usize, height: usize) -> Option<Projection> {
        let v = p - self.position;
        let z = v.dot(self.forward);
        if z.is_nan() || z <= 0.0 {
            return None;
        }
        // Perspective divide onto the plane at distance 1, then the inverse of `ray`'s map
        // sx = (2x/w − 1)·tan_half_x, sy = (1 − 2y/h)·tan_half_y.
        let sx = v.dot(self.right) / z;
        let sy = v.dot(self.up) / z;
        let x = (sx / self.tan_half_x + 1.0) * 0.5 * width as f64;
        let y = (1.0 - sy / self.tan_half_y) * 0.5 * height as f64;
        if !(x >= 0.0 && x < width as f64 && y >= 0.0 && y < height as f64) {
            return None;
        }
        let distance = v.length();
        Some(Projection {
            x,
            y,
            direction: v / distance,
            distance,
            cos_theta: (z / distance).min(1.0),
        })
    }

    /// Unit view direction (the axis the film plane is normal to).
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// Area of one pixel on the film plane at distance 1 from the eye, in units of that
    /// distance squared: A_pix = (2 tan_half_x)(2 tan_half_y)/(width·height).
    pub fn pixel_area(&self, width: usize, height: usize) -> f64 {
        4.0 * self.tan_half_x * self.tan_half_y / (width * height) as f64
    }

    /// Pinhole importance W_e (sr⁻¹, per unit sensor-projected solid angle) of the pixel a
    /// direction at angle θ to the forward axis falls in: 1/(A_pix cos⁴θ), so that
    /// ∫_pixel W_e cos θ dω = 1 (see the module doc; PBR 3rd ed., §16.1.1, eq. 16.3's form).
    pub fn importance(&self, cos_theta: f64, width: usize, height: usize) -> f64 {
        let c2 = cos_theta * cos_theta;
        1.0 / (self.pixel_area(width, height) * c2 * c2)
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

    fn tilted() -> Camera {
        Camera::new(
            Vec3::new(1.0, -2.0, 0.5),
            Vec3::new(0.3, 0.7, 4.0),
            Vec3::new(0.1, 1.0, 0.0),
            50.0,
            48.0 / 32.0,
        )
    }

    #[test]
    fn projection_inverts_ray() {
        let c = tilted();
        let (w, h) = (48, 32);
        let mut rng = crate::math::rng::SampleStream::new(7, 0, 0);
        for _ in 0..1000 {
            let (x, y) = (rng.next_f64() * w as f64, rng.next_f64() * h as f64);
            let t = 0.1 + 10.0 * rng.next_f64();
            let r = c.ray(x, y, w, h);
            let p = c.project(r.at(t), w, h).unwrap();
            assert!(
                (p.x - x).abs() < 1e-9 && (p.y - y).abs() < 1e-9,
                "{x} {y} {p:?}"
            );
            assert!((p.direction - r.d).length() < 1e-12);
            assert!((p.distance - t).abs() < 1e-9 * t);
            assert!((p.cos_theta - r.d.dot(c.forward)).abs() < 1e-12);
        }
        // behind the eye, and outside the image
        assert!(c.project(c.position - c.forward, w, h).is_none());
        assert!(c.project(c.position, w, h).is_none());
        let outside = c.ray(-0.5, 3.0, w, h).at(2.0);
        assert!(c.project(outside, w, h).is_none());
        let below = c.ray(3.0, h as f64 + 0.5, w, h).at(2.0);
        assert!(c.project(below, w, h).is_none());
    }

    #[test]
    fn importance_integrates_to_one_over_a_pixel() {
        // ∫_pixel W_e cos θ dω by Monte Carlo over solid angle, independently of the film-plane
        // mapping: directions uniform in a cone around the pixel centre that contains the
        // whole pixel (pdf 1/(2π(1 − cos α)), the solid angle of a cone), kept when they
        // project into the pixel.
        let c = tilted();
        let (w, h) = (48, 32);
        let mut rng = crate::math::rng::SampleStream::new(3, 0, 0);
        for (px, py) in [(0usize, 0usize), (20, 15), (47, 31)] {
            let axis = c.ray(px as f64 + 0.5, py as f64 + 0.5, w, h).d;
            let cos_alpha = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|(dx, dy)| c.ray(px as f64 + dx, py as f64 + dy, w, h).d.dot(axis))
                .fold(1.0f64, f64::min)
                - 1e-7;
            let pdf = 1.0 / (2.0 * crate::math::PI * (1.0 - cos_alpha));
            let frame = crate::math::frame::Frame::from_normal(axis);
            let n = 200_000;
            let (mut sum, mut sum2) = (0.0, 0.0);
            for _ in 0..n {
                let [u, v] = rng.next_2d();
                let cz = 1.0 - u * (1.0 - cos_alpha);
                let sz = (1.0 - cz * cz).max(0.0).sqrt();
                let phi = 2.0 * crate::math::PI * v;
                let d = frame.to_world(Vec3::new(sz * phi.cos(), sz * phi.sin(), cz));
                let f = match c.project(c.position + d, w, h) {
                    Some(p) if (p.x as usize, p.y as usize) == (px, py) => {
                        c.importance(p.cos_theta, w, h) * p.cos_theta / pdf
                    }
                    _ => 0.0,
                };
                sum += f;
                sum2 += f * f;
            }
            let mean = sum / n as f64;
            let se = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            assert!(
                (mean - 1.0).abs() <= 4.0 * se && se < 0.01,
                "pixel ({px}, {py}): {mean} ± {se}"
            );
        }
    }
}
