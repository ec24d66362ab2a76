//! Rotations and rigid frames in three dimensions: small `Copy` values,
//! no allocation, the transcendental functions from `libm` (the same bits
//! on every platform, as the rest of the crate).

use core::ops::Mul;

/// A point or a direction, metres or unitless: `[x, y, z]`.
pub type Vec3 = [f64; 3];

/// `a + b`.
#[inline]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a - b`.
#[inline]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `k a`.
#[inline]
pub fn scale(k: f64, a: Vec3) -> Vec3 {
    [k * a[0], k * a[1], k * a[2]]
}

/// The dot product.
#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The cross product `a x b`.
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The Euclidean length.
#[inline]
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// A rotation as a 3 x 3 matrix, row by row; its columns are the rotated
/// frame's axes in the reference frame. Kept orthonormal by construction
/// (products of elementary rotations; [`normalized`](Self::normalized)
/// repairs rounding drift).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rotation(pub [[f64; 3]; 3]);

impl Rotation {
    /// No rotation.
    pub const IDENTITY: Rotation = Rotation([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);

    /// About the x axis by `angle` rad.
    pub fn about_x(angle: f64) -> Rotation {
        let (s, c) = libm::sincos(angle);
        Rotation([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    }

    /// About the y axis by `angle` rad.
    pub fn about_y(angle: f64) -> Rotation {
        let (s, c) = libm::sincos(angle);
        Rotation([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    }

    /// About the z axis by `angle` rad.
    pub fn about_z(angle: f64) -> Rotation {
        let (s, c) = libm::sincos(angle);
        Rotation([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    }

    /// The rotation about the unit direction of `v` by `|v|` rad (the
    /// exponential map; the identity for `v = 0`).
    pub fn from_rotation_vector(v: Vec3) -> Rotation {
        let angle = norm(v);
        if angle < 1e-12 {
            // First order: I + [v]x, orthonormal to rounding.
            return Rotation([[1.0, -v[2], v[1]], [v[2], 1.0, -v[0]], [-v[1], v[0], 1.0]])
                .normalized();
        }
        let [x, y, z] = scale(1.0 / angle, v);
        let (s, c) = libm::sincos(angle);
        let t = 1.0 - c;
        Rotation([
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ])
    }

    /// The rotation vector (axis times angle, the angle in [0, pi]): the
    /// inverse of [`from_rotation_vector`](Self::from_rotation_vector).
    pub fn rotation_vector(&self) -> Vec3 {
        let m = &self.0;
        let angle = self.angle();
        let w = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]];
        if angle < 1e-9 {
            return scale(0.5, w);
        }
        let s = libm::sin(angle);
        if s > 1e-6 {
            return scale(angle / (2.0 * s), w);
        }
        // Near a half turn: the axis from the symmetric part, its sign
        // from the (small) antisymmetric part.
        let d = [
            ((m[0][0] + 1.0) / 2.0).max(0.0).sqrt(),
            ((m[1][1] + 1.0) / 2.0).max(0.0).sqrt(),
            ((m[2][2] + 1.0) / 2.0).max(0.0).sqrt(),
        ];
        let k = (0..3).max_by(|&a, &b| d[a].total_cmp(&d[b])).unwrap_or(0);
        let mut axis = [0.0; 3];
        for (j, slot) in axis.iter_mut().enumerate() {
            *slot = if j == k {
                d[k]
            } else {
                (m[k][j] + m[j][k]) / (4.0 * d[k])
            };
        }
        if dot(axis, w) < 0.0 {
            axis = scale(-1.0, axis);
        }
        scale(angle / norm(axis), axis)
    }

    /// The angle of the rotation, rad, in [0, pi].
    pub fn angle(&self) -> f64 {
        // atan2 of the sine (half the antisymmetric part's length) and the
        // cosine: accurate at every angle, where acos of the trace loses
        // half its digits near 0.
        let m = &self.0;
        let c = 0.5 * (m[0][0] + m[1][1] + m[2][2] - 1.0);
        let w = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]];
        libm::atan2(0.5 * norm(w), c)
    }

    /// The angle of the rotation that takes `self` to `other`, rad (the
    /// orientation error between two frames).
    pub fn angle_to(&self, other: &Rotation) -> f64 {
        (self.transpose() * *other).angle()
    }

    /// The inverse rotation.
    pub fn transpose(&self) -> Rotation {
        let m = &self.0;
        Rotation([
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ])
    }

    /// Column `i` (the rotated frame's axis `i`); `[0; 3]` beyond 2.
    pub fn column(&self, i: usize) -> Vec3 {
        let m = &self.0;
        match i {
            0..=2 => [m[0][i], m[1][i], m[2][i]],
            _ => [0.0; 3],
        }
    }

    /// `v` rotated.
    #[inline]
    pub fn apply(&self, v: Vec3) -> Vec3 {
        let m = &self.0;
        [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
    }

    /// The nearest rotation by Gram-Schmidt on the columns (repairs the
    /// drift of long products).
    pub fn normalized(&self) -> Rotation {
        let x = self.column(0);
        let x = scale(1.0 / norm(x), x);
        let y = self.column(1);
        let y = sub(y, scale(dot(x, y), x));
        let y = scale(1.0 / norm(y), y);
        let z = cross(x, y);
        Rotation::from_columns(x, y, z)
    }

    /// The rotation whose columns are `x`, `y`, `z`.
    pub fn from_columns(x: Vec3, y: Vec3, z: Vec3) -> Rotation {
        Rotation([[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]])
    }

    /// Whether every element is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|v| v.is_finite())
    }
}

impl Mul for Rotation {
    type Output = Rotation;

    fn mul(self, rhs: Rotation) -> Rotation {
        let (a, b) = (&self.0, &rhs.0);
        let mut m = [[0.0; 3]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
            }
        }
        Rotation(m)
    }
}

/// A rigid transform: rotate, then translate (`p' = R p + t`). As a pose,
/// the frame's axes ([`Rotation`] columns) and origin in its reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// The orientation.
    pub rotation: Rotation,
    /// The origin, metres.
    pub translation: Vec3,
}

impl Frame {
    /// No motion.
    pub const IDENTITY: Frame = Frame {
        rotation: Rotation::IDENTITY,
        translation: [0.0; 3],
    };

    /// A frame from its parts.
    pub fn new(rotation: Rotation, translation: Vec3) -> Frame {
        Frame {
            rotation,
            translation,
        }
    }

    /// A pure rotation.
    pub fn rotation(rotation: Rotation) -> Frame {
        Frame::new(rotation, [0.0; 3])
    }

    /// A pure translation.
    pub fn translation(t: Vec3) -> Frame {
        Frame::new(Rotation::IDENTITY, t)
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Frame {
        let r = self.rotation.transpose();
        Frame::new(r, scale(-1.0, r.apply(self.translation)))
    }

    /// The point `p` transformed.
    #[inline]
    pub fn apply(&self, p: Vec3) -> Vec3 {
        add(self.rotation.apply(p), self.translation)
    }

    /// Whether every element is finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.is_finite() && self.translation.iter().all(|v| v.is_finite())
    }
}

impl Mul for Frame {
    type Output = Frame;

    fn mul(self, rhs: Frame) -> Frame {
        Frame::new(self.rotation * rhs.rotation, self.apply(rhs.translation))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: &Rotation, b: &Rotation, tol: f64) -> bool {
        a.0.iter()
            .flatten()
            .zip(b.0.iter().flatten())
            .all(|(x, y)| (x - y).abs() < tol)
    }

    #[test]
    fn elementary_rotations_turn_the_axes_the_right_way() {
        let rz = Rotation::about_z(core::f64::consts::FRAC_PI_2);
        let x = rz.apply([1.0, 0.0, 0.0]);
        assert!((x[1] - 1.0).abs() < 1e-15 && x[0].abs() < 1e-15);
        let rx = Rotation::about_x(core::f64::consts::FRAC_PI_2);
        let y = rx.apply([0.0, 1.0, 0.0]);
        assert!((y[2] - 1.0).abs() < 1e-15);
        let ry = Rotation::about_y(core::f64::consts::FRAC_PI_2);
        let z = ry.apply([0.0, 0.0, 1.0]);
        assert!((z[0] - 1.0).abs() < 1e-15);
    }

    proptest! {
        #[test]
        fn rotation_vectors_round_trip(
            x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0, angle in 0.0f64..3.1,
        ) {
            let n = norm([x, y, z]);
            prop_assume!(n > 1e-3);
            let v = scale(angle / n, [x, y, z]);
            let r = Rotation::from_rotation_vector(v);
            prop_assert!((r.angle() - angle).abs() < 1e-9);
            let back = r.rotation_vector();
            prop_assert!(norm(sub(back, v)) < 1e-8, "{v:?} {back:?}");
            // Orthonormal.
            prop_assert!(close(&(r.transpose() * r), &Rotation::IDENTITY, 1e-12));
        }

        #[test]
        fn frames_compose_and_invert(
            a in -3.0f64..3.0, b in -3.0f64..3.0, t in -1.0f64..1.0,
        ) {
            let f = Frame::new(
                Rotation::about_z(a) * Rotation::about_x(b),
                [t, 2.0 * t, -t],
            );
            let g = f * f.inverse();
            prop_assert!(close(&g.rotation, &Rotation::IDENTITY, 1e-12));
            prop_assert!(norm(g.translation) < 1e-12);
            let p = [0.3, -0.2, 0.1];
            let q = f.inverse().apply(f.apply(p));
            prop_assert!(norm(sub(p, q)) < 1e-12);
        }
    }

    #[test]
    fn half_turns_keep_their_axis() {
        for axis in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, 0.0, 0.8]] {
            let v = scale(core::f64::consts::PI, axis);
            let back = Rotation::from_rotation_vector(v).rotation_vector();
            // The axis or its opposite: both describe the half turn.
            let same = norm(sub(back, v)) < 1e-6 || norm(add(back, v)) < 1e-6;
            assert!(same, "{back:?}");
        }
    }
}
