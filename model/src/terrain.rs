//! The kinds of terrain of legged_gym that the paper compares gaits on; the simulator
//! builds them (`gaitsweep_sim::terrain`).

use crate::error::Error;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// The kinds of terrain.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, PartialOrd, Ord)]
#[serde(rename_all = "lowercase")]
pub enum TerrainKind {
    /// A flat plane.
    Flat,
    /// Random uniform heightfield.
    Rough,
    /// Pyramid stairs, up for even robots, down for odd ones.
    Stairs,
    /// Pyramid slopes, up for even robots, down for odd ones.
    Slopes,
    /// legged_gym's mixed terrain: robots dealt to slopes, rough ground and stairs up and
    /// down in legged_gym's proportions, all in one curriculum.
    Mixed,
}

impl TerrainKind {
    /// All kinds.
    pub const ALL: [TerrainKind; 5] = [
        Self::Flat,
        Self::Rough,
        Self::Stairs,
        Self::Slopes,
        Self::Mixed,
    ];
}

impl fmt::Display for TerrainKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Flat => "flat",
            Self::Rough => "rough",
            Self::Stairs => "stairs",
            Self::Slopes => "slopes",
            Self::Mixed => "mixed",
        })
    }
}

impl FromStr for TerrainKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        match s.to_ascii_lowercase().as_str() {
            "flat" => Ok(Self::Flat),
            "rough" => Ok(Self::Rough),
            "stairs" => Ok(Self::Stairs),
            "slopes" | "slope" => Ok(Self::Slopes),
            "mixed" => Ok(Self::Mixed),
            other => Err(Error::InvalidArgument(format!(
                "unknown terrain {other:?}; expected flat, rough, stairs, slopes or mixed"
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in TerrainKind::ALL {
            assert_eq!(k.to_string().parse::<TerrainKind>().unwrap(), k);
        }
        assert!("lava".parse::<TerrainKind>().is_err());
    }
}
