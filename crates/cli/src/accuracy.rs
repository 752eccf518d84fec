//! `fibfluid accuracy`: placeholder until the accuracy study lands.

use std::path::Path;

use fibfluid::Error;

pub fn run(
    _scene: &Path,
    _out: &Path,
    _steps: &[usize],
    _backends: Option<Vec<String>>,
    _modes: Option<Vec<String>>,
) -> Result<(), Error> {
    Err(Error::Invalid("accuracy: not built yet".into()))
}
