//! The analysis lattice: auto-fit of a cubic mass-spring lattice around a display mesh
//! ([`fit`]) and the trilinear embedding of the mesh in it ([`embed`]).

use serde::{Deserialize, Serialize};

/// Which springs each cell carries (Miyazaki Fig. 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SpringLayout {
    /// Cell edges + one diagonal per square face: the fewest springs (Table 1).
    #[default]
    FaceDiagonals,
    /// Cell edges + the four body diagonals.
    BodyDiagonals,
    /// Cell edges + face diagonals + body diagonals.
    Both,
}
