//! The limits every file reader shares.

/// Default largest file a reader accepts: 2 GiB. A larger one is refused before anything is
/// allocated for it. Override it per call ([`ReadOptions::max_bytes`]), per process
/// ([`set_max_file_bytes`], the CLI's `--max-file-bytes`) or with the environment variable
/// [`MAX_FILE_BYTES_ENV`].
pub const DEFAULT_MAX_FILE_BYTES: u64 = 2 << 30;

/// Environment variable that overrides [`DEFAULT_MAX_FILE_BYTES`]: a byte count with an
/// optional binary suffix (`K`, `M`, `G`, `T`, e.g. `4G`); see [`parse_byte_count`].
pub const MAX_FILE_BYTES_ENV: &str = "FIBFLUID_MAX_FILE_BYTES";
