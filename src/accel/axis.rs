//! Stage: accel. Axis arithmetic shared by the triangle tests: [`super::triaccel`]
//! projects along a triangle's largest axis, [`super::watertight`] shears along the
//! ray's; both name the other two axes the same way.

/// `(k + 1) % 3` and `(k + 2) % 3` without a division: `MOD3[k + 1]`, `MOD3[k + 2]`.
pub const MOD3: [usize; 5] = [0, 1, 2, 0, 1];
