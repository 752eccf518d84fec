//! Length units: the unit a mesh file (`[mesh] unit`) or a label image (`xyzt_units`)
//! stores lengths in. Everything inside is in metres.

use fibfluid_linalg::{Choice, impl_choice};

/// A length unit: positions are converted to metres on reading and back on writing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LengthUnit {
    /// Metres (the default).
    #[default]
    Metre,
    /// Centimetres.
    Centimetre,
    /// Millimetres.
    Millimetre,
    /// Micrometres.
    Micrometre,
}

impl Choice for LengthUnit {
    const WHAT: &'static str = "length unit";
    const ALL: &'static [Self] =
        &[LengthUnit::Metre, LengthUnit::Centimetre, LengthUnit::Millimetre, LengthUnit::Micrometre];
    fn name(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Millimetre => "mm",
            LengthUnit::Micrometre => "um",
        }
    }
}
impl_choice!(LengthUnit);

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 1e-2,
            LengthUnit::Millimetre => 1e-3,
            LengthUnit::Micrometre => 1e-6,
        }
    }
}
