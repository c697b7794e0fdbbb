//! Packet twins of [`crate::accel::prims`]: spheres, boxes and planes against a whole
//! packet, in the scalar tests' operation order.
