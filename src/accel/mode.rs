//! Stage: accel. [`Mode`]: which of the accelerator's entry points trace a batch of
//! rays, at which width; the one choice `raypack bench`, `trace` and `render` make.

use super::tile_lanes;
#[cfg(doc)]
use super::{Accel, kdtree};
use crate::simd::native_lanes;

/// Which entry points trace rays, at which width: the one mode `raypack bench`,
/// `trace` and `render` select.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Mode {
    /// One ray at a time: the reference.
    #[default]
    Scalar,
    /// 4 consecutive rays per packet (SSE registers): the Wald packet.
    Packet4,
    /// 8 consecutive rays per packet (AVX2 registers).
    Packet8,
    /// 16 consecutive rays per packet (AVX-512 registers).
    Packet16,
    /// 64 consecutive rays as one tile of SIMD groups of the native width, sharing an
    /// entry point ([`kdtree::traverse_tile`]).
    Tile64,
    /// Each chunk of rays as one stream ([`Accel::intersect_stream`]): for incoherent
    /// rays, one ray per SIMD lane, each on its own walk. The renderer traces this
    /// mode's rays as in scalar mode.
    Stream,
}

impl Mode {
    /// Every mode, narrowest first.
    pub const ALL: [Mode; 6] = [
        Mode::Scalar,
        Mode::Packet4,
        Mode::Packet8,
        Mode::Packet16,
        Mode::Tile64,
        Mode::Stream,
    ];

    /// The name the command line takes and the reports print.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Scalar => "scalar",
            Mode::Packet4 => "packet4",
            Mode::Packet8 => "packet8",
            Mode::Packet16 => "packet16",
            Mode::Tile64 => "tile64",
            Mode::Stream => "stream",
        }
    }

    /// Rays traced together (1 for scalar and stream, whose rays share nothing).
    pub fn packet_size(self) -> usize {
        match self {
            Mode::Scalar | Mode::Stream => 1,
            Mode::Packet4 => 4,
            Mode::Packet8 => 8,
            Mode::Packet16 => 16,
            Mode::Tile64 => 64,
        }
    }

    /// SIMD lanes of the kernels (1 for scalar).
    pub fn width(self) -> usize {
        match self {
            Mode::Tile64 => tile_lanes(),
            _ => self.packet_size(),
        }
    }

    /// The packet mode that traces this mode's SIMD groups one at a time: a tile's
    /// groups for [`Mode::Tile64`], scalar for [`Mode::Stream`], the mode itself
    /// otherwise.
    pub fn group_mode(self) -> Mode {
        match (self, tile_lanes()) {
            (Mode::Tile64, 16) => Mode::Packet16,
            (Mode::Tile64, _) => Mode::Packet8,
            (Mode::Stream, _) => Mode::Scalar,
            (m, _) => m,
        }
    }

    /// The packet mode of the widest registers this CPU runs natively.
    pub fn native_packet() -> Mode {
        match native_lanes() {
            16 => Mode::Packet16,
            8 => Mode::Packet8,
            _ => Mode::Packet4,
        }
    }

    /// Parses a comma-separated list of modes, where `all` stands for [`Mode::ALL`].
    pub fn parse_list(s: &str) -> Result<Vec<Mode>, String> {
        let mut out = Vec::new();
        for name in s.split(',') {
            if name == "all" {
                out.extend(Mode::ALL);
            } else {
                out.push(
                    name.parse()
                        .map_err(|_| unknown_mode(name, ", packet or all"))?,
                );
            }
        }
        out.dedup();
        Ok(out)
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Mode {
    type Err = String;
    /// `packet` names the native packet mode ([`Mode::native_packet`]).
    fn from_str(s: &str) -> Result<Mode, String> {
        match s {
            "scalar" => Ok(Mode::Scalar),
            "packet" => Ok(Mode::native_packet()),
            "packet4" => Ok(Mode::Packet4),
            "packet8" => Ok(Mode::Packet8),
            "packet16" => Ok(Mode::Packet16),
            "tile64" => Ok(Mode::Tile64),
            "stream" => Ok(Mode::Stream),
            _ => Err(unknown_mode(s, " or packet")),
        }
    }
}

/// The error for an unknown mode name: every mode's name, then `more` (the names a
/// caller accepts beside them).
fn unknown_mode(name: &str, more: &str) -> String {
    let names: Vec<&str> = Mode::ALL.iter().map(|m| m.name()).collect();
    format!("unknown mode `{name}`: expected {}{more}", names.join(", "))
}
