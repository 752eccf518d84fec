//! `series.pvd`: a ParaView collection of a timed run's volume at each output time
//! (`volume_NNNN.vtu`, as `volume.vtu`), each written as its output comes.

use std::io::Write;
use std::path::{Path, PathBuf};

use fibfluid::geometry::LengthUnit;
use fibfluid::sim::hyper_run::TimeFrame;

use crate::output::{nanos, parent_of};
use crate::series::SERIES_FILE;
use crate::vtu::VolumeView;
use crate::{Error, Result};

/// The ParaView collection of a timed run's volumes, one per output time.
pub const SERIES_PVD: &str = "series.pvd";

/// The volume file of output `index` (`volume_0000.vtu` at `t = 0`).
pub fn frame_file(index: usize) -> String {
    format!("volume_{index:04}.vtu")
}

/// Every file a timed run with `outputs` output times writes besides the usual ones:
/// [`SERIES_FILE`], [`SERIES_PVD`] and one [`frame_file`] per output.
pub fn timed_files(outputs: usize) -> Vec<String> {
    let mut names = vec![SERIES_FILE.to_string(), SERIES_PVD.to_string()];
    names.extend((0..outputs).map(frame_file));
    names
}

/// Writes a timed run's volume at each output time as it comes, so memory holds one
/// output's volume at a time: into a staging directory beside the output directory, which
/// [`FrameWriter::finish`] completes with [`SERIES_PVD`] and moves into it once the run has
/// succeeded (and the usual files are written). Dropped unfinished, it removes what it
/// wrote; the output directory is not touched.
#[derive(Debug)]
pub struct FrameWriter {
    out: PathBuf,
    name: String,
    unit: LengthUnit,
    staging: Option<PathBuf>,
    /// Each written output's time (s), by index.
    times: Vec<f64>,
    error: Option<Error>,
}

impl FrameWriter {
    /// A writer for the output directory `out` of the scene `name`, lengths written in
    /// `unit`. Nothing is created before the first output.
    pub fn new(out: &Path, name: &str, unit: LengthUnit) -> Self {
        Self {
            out: out.to_path_buf(),
            name: name.to_string(),
            unit,
            staging: None,
            times: Vec::new(),
            error: None,
        }
    }

    /// Writes `frame`'s volume (an output seen again, as after a solve started over,
    /// replaces it and drops those after it). After a failure it writes nothing more and
    /// [`FrameWriter::finish`] reports the failure.
    pub fn write(&mut self, frame: &TimeFrame<'_>) {
        if self.error.is_none()
            && let Err(e) = self.try_write(frame)
        {
            self.error = Some(e);
        }
    }

    fn try_write(&mut self, frame: &TimeFrame<'_>) -> Result<()> {
        let file = frame_file(frame.index);
        let shown = self.out.join(&file);
        let io = |source| Error::Io { path: shown.clone(), source };
        let staging = match &self.staging {
            Some(s) => s.clone(),
            None => {
                let parent = parent_of(&self.out);
                std::fs::create_dir_all(&parent).map_err(io)?;
                let s = parent.join(format!(".fibfluid-frames-{}-{}", std::process::id(), nanos()));
                std::fs::create_dir(&s).map_err(io)?;
                self.staging = Some(s.clone());
                s
            }
        };
        let at = format!("{} at t = {} s", self.name, frame.row.time);
        let comment = crate::vtu::volume_comment(&at, frame.tissue, self.unit);
        let mut f = std::io::BufWriter::new(std::fs::File::create(staging.join(&file)).map_err(io)?);
        crate::vtu::write_volume(&mut f, &comment, self.unit, &VolumeView::of_fields(frame.fields))
            .and_then(|()| f.flush())
            .map_err(io)?;
        self.times.truncate(frame.index);
        self.times.push(frame.row.time);
        Ok(())
    }

    /// Writes [`SERIES_PVD`] beside the volumes and moves them all into the output
    /// directory; the paths written (none for a run without outputs in time).
    ///
    /// Errors: the first failure of [`FrameWriter::write`]; writing or moving a file.
    pub fn finish(mut self) -> Result<Vec<PathBuf>> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let Some(staging) = self.staging.clone() else { return Ok(Vec::new()) };
        let pvd = self.out.join(SERIES_PVD);
        std::fs::write(staging.join(SERIES_PVD), self.collection())
            .map_err(|source| Error::Io { path: pvd.clone(), source })?;
        std::fs::create_dir_all(&self.out).map_err(|source| Error::Io { path: self.out.clone(), source })?;
        let mut written = Vec::new();
        let names = (0..self.times.len()).map(frame_file).chain([SERIES_PVD.to_string()]);
        for name in names {
            let to = self.out.join(&name);
            std::fs::rename(staging.join(&name), &to)
                .map_err(|source| Error::Io { path: to.clone(), source })?;
            written.push(to);
        }
        Ok(written)
    }

    /// The collection file: each volume with its time.
    fn collection(&self) -> String {
        let mut out = String::from("<?xml version=\"1.0\"?>\n");
        out += "<VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n";
        out += &format!(
            "<!-- fibfluid {}: the volume at each output time (s) -->\n",
            crate::vtu::comment_text(&self.name)
        );
        out += "<Collection>\n";
        for (k, t) in self.times.iter().enumerate() {
            out +=
                &format!("<DataSet timestep=\"{t:?}\" group=\"\" part=\"0\" file=\"{}\"/>\n", frame_file(k));
        }
        out + "</Collection>\n</VTKFile>\n"
    }
}

impl Drop for FrameWriter {
    fn drop(&mut self) {
        if let Some(s) = &self.staging {
            let _ = std::fs::remove_dir_all(s);
        }
    }
}
