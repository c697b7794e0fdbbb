//! Packet twin of [`crate::accel::triaccel`]: one TriAccel record against `LANES` rays.
