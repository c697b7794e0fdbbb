//! What a program that traces rays needs, in one `use raypack::prelude::*;`: the
//! kd-tree and the 8-wide BVH, the accelerator interface with its packet and batch forms, rays and hits,
//! geometry and the OBJ loader, the packet widths, and glam's `Vec3` (so a user does not
//! add glam to call the API).

pub use crate::accel::bvh::Bvh;
pub use crate::accel::kdtree::KdTree;
pub use crate::accel::{Accel, HitPacket, PacketTrace, RayPacket};
pub use crate::ray::{Hit, Ray};
pub use crate::scene::{Aabb, Geometry, obj};
pub use crate::simd::{W4, W8, W16};
pub use glam::Vec3;
