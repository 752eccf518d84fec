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

    /// Units per metre: whole numbers, exact in f64, so [`Self::to_metres`] and
    /// [`Self::from_metres`] round once (a length typed in millimetres and the same length
    /// typed in metres give the same f64).
    pub fn per_metre(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Centimetre => 1e2,
            LengthUnit::Millimetre => 1e3,
            LengthUnit::Micrometre => 1e6,
        }
    }

    /// A length in this unit, in metres, correctly rounded (`x / per_metre`: multiplying by
    /// [`Self::metres`], itself rounded, may be one unit in the last place off).
    pub fn to_metres(self, x: f64) -> f64 {
        x / self.per_metre()
    }

    /// A length in metres, in this unit, correctly rounded.
    pub fn from_metres(self, x: f64) -> f64 {
        x * self.per_metre()
    }
}
