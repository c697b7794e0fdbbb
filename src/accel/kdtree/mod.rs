//! SAH kd-tree: build (Wald & Havran 2006), scalar and packet traversal.

pub mod node;
