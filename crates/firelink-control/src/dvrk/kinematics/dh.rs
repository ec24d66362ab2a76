//! Denavit-Hartenberg links as the dVRK's kinematic files write them
//! (`share/kinematic/*.json`, `share/tool/*.json`): `alpha`, `A`, `theta`,
//! `D`, a joint `offset` added to the joint value, a type and the joint
//! limits, under the file's convention.

use super::KinematicsError;
use super::frame::{Frame, Rotation};

/// How a link's four parameters compose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Classic DH (the MTM's file): `Rz(theta) Tz(d) Tx(a) Rx(alpha)`.
    Standard,
    /// Craig's modified DH (the PSM's and its tools' files):
    /// `Rx(alpha) Tx(a) Rz(theta) Tz(d)`.
    Modified,
}

/// What a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Turns about z: the joint value adds to `theta`, rad.
    Revolute,
    /// Slides along z: the joint value adds to `d`, m.
    Prismatic,
}

/// One link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhLink {
    /// Twist, rad.
    pub alpha: f64,
    /// Length, m.
    pub a: f64,
    /// Joint angle at joint value 0 before the offset, rad.
    pub theta: f64,
    /// Offset along z at joint value 0 before the offset, m.
    pub d: f64,
    /// Added to the joint value (rad or m).
    pub offset: f64,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// The joint's limits, (lower, upper), rad or m.
    pub limits: (f64, f64),
}

impl DhLink {
    /// A revolute link (`theta` 0).
    pub const fn revolute(alpha: f64, a: f64, d: f64, offset: f64, limits: (f64, f64)) -> DhLink {
        DhLink {
            alpha,
            a,
            theta: 0.0,
            d,
            offset,
            kind: JointKind::Revolute,
            limits,
        }
    }

    /// A prismatic link (`theta` 0).
    pub const fn prismatic(alpha: f64, a: f64, d: f64, offset: f64, limits: (f64, f64)) -> DhLink {
        DhLink {
            alpha,
            a,
            theta: 0.0,
            d,
            offset,
            kind: JointKind::Prismatic,
            limits,
        }
    }

    /// The link's transform at joint value `q`.
    pub fn frame(&self, convention: Convention, q: f64) -> Frame {
        let (theta, d) = match self.kind {
            JointKind::Revolute => (self.theta + q + self.offset, self.d),
            JointKind::Prismatic => (self.theta, self.d + q + self.offset),
        };
        let rz = Rotation::about_z(theta);
        let rx = Rotation::about_x(self.alpha);
        match convention {
            Convention::Standard => {
                // Rz(theta) Tz(d) Tx(a) Rx(alpha): origin at Rz (a, 0, 0) + (0, 0, d).
                let x = rz.apply([self.a, 0.0, 0.0]);
                Frame::new(rz * rx, [x[0], x[1], x[2] + d])
            }
            Convention::Modified => {
                // Rx(alpha) Tx(a) Rz(theta) Tz(d): origin at (a, 0, 0) + Rx (0, 0, d).
                let z = rx.apply([0.0, 0.0, d]);
                Frame::new(rx * rz, [self.a + z[0], z[1], z[2]])
            }
        }
    }

    /// Whether `q` is within the joint's limits, widened by `slack`.
    pub fn allows(&self, q: f64, slack: f64) -> bool {
        self.limits.0 - slack <= q && q <= self.limits.1 + slack
    }
}

/// The first joint of `q` outside its link's limits (widened by 1e-9),
/// as the error an inverse returns.
pub fn out_of_limits(links: &[DhLink], q: &[f64]) -> Option<KinematicsError> {
    links
        .iter()
        .zip(q)
        .enumerate()
        .find(|(_, (l, q))| !l.allows(**q, 1e-9))
        .map(|(joint, (l, &value))| KinematicsError::JointLimit {
            joint,
            value,
            lower: l.limits.0,
            upper: l.limits.1,
        })
}

/// The transform of a chain of links at joint values `q` (as many links as
/// both have).
pub fn chain(links: &[DhLink], convention: Convention, q: &[f64]) -> Frame {
    links.iter().zip(q).fold(Frame::IDENTITY, |f, (link, &q)| {
        f * link.frame(convention, q)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dvrk::kinematics::frame::{norm, sub};

    fn link(alpha: f64, a: f64, d: f64, kind: JointKind) -> DhLink {
        DhLink {
            alpha,
            a,
            theta: 0.0,
            d,
            offset: 0.0,
            kind,
            limits: (-1.0, 1.0),
        }
    }

    #[test]
    fn both_conventions_compose_their_four_elementary_motions() {
        let l = link(0.4, 0.2, 0.1, JointKind::Revolute);
        let q = 0.7;
        let rz = Frame::rotation(Rotation::about_z(q));
        let rx = Frame::rotation(Rotation::about_x(0.4));
        let tz = Frame::translation([0.0, 0.0, 0.1]);
        let tx = Frame::translation([0.2, 0.0, 0.0]);
        let standard = rz * tz * tx * rx;
        let modified = rx * tx * rz * tz;
        for (got, want) in [
            (l.frame(Convention::Standard, q), standard),
            (l.frame(Convention::Modified, q), modified),
        ] {
            assert!(norm(sub(got.translation, want.translation)) < 1e-15);
            assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
        }
        // A prismatic joint adds to d.
        let p = link(0.0, 0.0, 0.1, JointKind::Prismatic);
        let f = p.frame(Convention::Modified, 0.05);
        assert!((f.translation[2] - 0.15).abs() < 1e-15);
    }
}
