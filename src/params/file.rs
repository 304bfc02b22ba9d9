//! Parameter files: a small subset of TOML, one `NAME = value` per line.
//!
//! ```toml
//! # rotorpilot parameters
//! MIS_TAKEOFF_ALT = 5.0
//! EST_ORDER = 4
//! # RTL_RETURN_ALT = 30.0    (default)
//! ```
//!
//! INT32 values are written as integers and REAL32 values with a decimal
//! point, in the shortest form that reads back to the same `f32`.
//! Parameters at their default are written commented out, so a file moved to
//! another airframe picks up that airframe's defaults (the masses).
//!
//! Reading goes line by line: an unknown name, a malformed line or a refused
//! value becomes a warning naming the line, and every other parameter is still
//! read. Writing is atomic ([`crate::statefile`]): the text goes to a
//! temporary file in the same directory, which is flushed to disk (`fsync`)
//! and then renamed over the target, so a crash at any point leaves either the
//! old file or the new one, never a truncated one.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::{PARAMS, ParamStore, ParamType, ParamValue};
use crate::airframe::Airframe;
use crate::statefile::{self, WriteError};

/// A parameter file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ParamFileError {
    /// Reading, writing, syncing or renaming failed.
    #[error("parameter file {path}: {source}")]
    Io {
        /// The file (or its temporary twin).
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The path names no file (e.g. `/` or `..`).
    #[error("parameter file {0}: not a file name")]
    NotAFile(PathBuf),
}

impl From<WriteError> for ParamFileError {
    fn from(e: WriteError) -> Self {
        match e {
            WriteError::Io { path, source } => ParamFileError::Io { path, source },
            WriteError::NotAFile(path) => ParamFileError::NotAFile(path),
        }
    }
}

/// A REAL32 value as TOML: always with a decimal point or exponent.
fn format_real(x: f32) -> String {
    let s = format!("{x}");
    if s.contains(['.', 'e', 'E']) || !x.is_finite() {
        s
    } else {
        format!("{s}.0")
    }
}

fn format_value(v: ParamValue) -> String {
    match v {
        ParamValue::Int32(i) => i.to_string(),
        ParamValue::Real32(x) => format_real(x),
    }
}

/// Parse a value for a parameter of type `kind`.
fn parse_value(text: &str, kind: ParamType) -> Result<ParamValue, String> {
    let t = text.trim().replace('_', "");
    match kind {
        ParamType::Int32 => {
            let i: i64 = t
                .parse()
                .map_err(|_| format!("`{text}` is not an integer (INT32 parameter)"))?;
            i32::try_from(i)
                .map(ParamValue::Int32)
                .map_err(|_| format!("{i} does not fit INT32"))
        }
        ParamType::Real32 => {
            // TOML spells infinity `inf`; Rust's parser reads it too and the store refuses it.
            let x: f32 = t.parse().map_err(|_| format!("`{text}` is not a number"))?;
            Ok(ParamValue::Real32(x))
        }
    }
}

impl ParamStore {
    /// The file text for this store (module doc).
    #[must_use]
    pub fn to_file_text(&self) -> String {
        let mut out = String::from(
            "# rotorpilot parameters: NAME = value, one per line (INT32 as integers, REAL32 as decimals).\n\
             # Parameters at their default are commented out.\n",
        );
        for (i, (spec, value)) in self.iter().enumerate() {
            let at_default = self.default_value(i) == Some(value);
            let unit = if spec.unit.is_empty() {
                String::new()
            } else {
                format!(" [{}]", spec.unit)
            };
            let line = format!("{} = {}", spec.name, format_value(value));
            if at_default {
                out.push_str(&format!("# {line}    (default){unit}\n"));
            } else if unit.is_empty() {
                out.push_str(&format!("{line}\n"));
            } else {
                out.push_str(&format!("{line}    #{unit}\n"));
            }
        }
        out
    }

    /// Apply the `NAME = value` lines of `text` to this store. Returns one
    /// warning per skipped line (`label:line: why`); every other line is applied.
    pub fn apply_file_text(&mut self, text: &str, label: &str) -> Vec<String> {
        let mut warnings = Vec::new();
        let mut seen = vec![false; PARAMS.len()];
        for (n, raw) in text.lines().enumerate() {
            let line_no = n + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let Some((name, value)) = line.split_once('=') else {
                warnings.push(format!("{label}:{line_no}: `{line}` is not `NAME = value`, skipped"));
                continue;
            };
            let name = name.trim().trim_matches('"');
            let Some(index) = self.index_of(name) else {
                warnings.push(format!(
                    "{label}:{line_no}: unknown parameter {name}{}, skipped",
                    super::did_you_mean(name)
                ));
                continue;
            };
            let kind = PARAMS[index].kind;
            let parsed = match parse_value(value, kind) {
                Ok(v) => v,
                Err(why) => {
                    warnings.push(format!("{label}:{line_no}: {name}: {why}, skipped"));
                    continue;
                }
            };
            if let Err(e) = self.set(name, parsed) {
                warnings.push(format!("{label}:{line_no}: {e}, skipped"));
                continue;
            }
            if seen[index] {
                warnings.push(format!("{label}:{line_no}: {name} given again, the last value wins"));
            }
            seen[index] = true;
        }
        warnings
    }

    /// Read a parameter file for `airframe`: defaults, then every valid line
    /// of the file. Returns the store and the warnings for skipped lines.
    ///
    /// # Errors
    /// The file cannot be read (missing, permissions). Bad content is never
    /// an error, only warnings.
    pub fn load(airframe: &Airframe, path: &Path) -> Result<(ParamStore, Vec<String>), ParamFileError> {
        let bytes = fs::read(path).map_err(|source| ParamFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let text = String::from_utf8_lossy(&bytes);
        let mut store = ParamStore::new(airframe);
        let warnings = store.apply_file_text(&text, &path.display().to_string());
        Ok((store, warnings))
    }

    /// [`Self::load`], or the defaults when the file does not exist yet.
    ///
    /// # Errors
    /// The file exists but cannot be read.
    pub fn load_or_default(airframe: &Airframe, path: &Path) -> Result<(ParamStore, Vec<String>), ParamFileError> {
        match Self::load(airframe, path) {
            Err(ParamFileError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                Ok((ParamStore::new(airframe), Vec::new()))
            }
            other => other,
        }
    }

    /// [`Self::load_or_default`], keeping a damaged file: when `path` has
    /// a line that does not read (an unknown name, a malformed line, a
    /// refused value, a name given twice) or is empty (no text at all: a
    /// truncated file, not a reset), it is renamed aside to
    /// [`set_aside_path`] (`params.bad-<unix_s>` next to it) before the
    /// caller saves the store over `path`; every valid line is still in the
    /// store. The warnings end with one naming where the file went.
    ///
    /// # Errors
    /// The file exists but cannot be read, or cannot be renamed aside.
    pub fn load_keeping_bad(airframe: &Airframe, path: &Path, unix_s: u64) -> Result<Loaded, ParamFileError> {
        let empty = fs::metadata(path).is_ok_and(|m| m.is_file())
            && fs::read(path).is_ok_and(|b| b.iter().all(u8::is_ascii_whitespace));
        let (store, mut warnings) = Self::load_or_default(airframe, path)?;
        if warnings.is_empty() && !empty {
            return Ok(Loaded {
                store,
                warnings,
                set_aside: None,
            });
        }
        let aside = set_aside_path(path, unix_s)?;
        fs::rename(path, &aside).map_err(|source| ParamFileError::Io {
            path: aside.clone(),
            source,
        })?;
        let why = if empty {
            "is empty"
        } else {
            "has lines that do not read"
        };
        warnings.push(format!(
            "{} {why}: kept as {}; the valid lines are in force, the rest at their defaults",
            path.display(),
            aside.display()
        ));
        Ok(Loaded {
            store,
            warnings,
            set_aside: Some(aside),
        })
    }

    /// Write the store to `path` atomically (module doc).
    ///
    /// # Errors
    /// Writing, syncing or renaming failed; the old file is then untouched
    /// and the temporary file removed.
    pub fn save(&self, path: &Path) -> Result<(), ParamFileError> {
        statefile::write_atomic(path, self.to_file_text().as_bytes(), |f, b| f.write_all(b))?;
        Ok(())
    }
}

/// A parameter file read by [`ParamStore::load_keeping_bad`].
#[derive(Debug)]
pub struct Loaded {
    /// The defaults and every valid line.
    pub store: ParamStore,
    /// One per skipped line, then where the file went when it was set aside.
    pub warnings: Vec<String>,
    /// Where the damaged file was renamed to.
    pub set_aside: Option<PathBuf>,
}

/// Where a damaged parameter file is kept: `<stem>.bad-<unix_s>` in the
/// same directory (`params.bad-1764669000`), `.1`, `.2`, ... appended when
/// that name is taken.
///
/// # Errors
/// [`ParamFileError::NotAFile`] for a path without a file name.
pub fn set_aside_path(path: &Path, unix_s: u64) -> Result<PathBuf, ParamFileError> {
    let stem = path
        .file_stem()
        .ok_or_else(|| ParamFileError::NotAFile(path.to_path_buf()))?
        .to_string_lossy()
        .into_owned();
    let base = format!("{stem}.bad-{unix_s}");
    let mut candidate = path.with_file_name(&base);
    let mut n = 0;
    while candidate.exists() {
        n += 1;
        candidate = path.with_file_name(format!("{base}.{n}"));
    }
    Ok(candidate)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_file_with_bad_lines_or_empty_is_kept_aside_and_a_good_one_is_not() {
        let dir = scratch("aside");
        let path = dir.join("params.toml");
        fs::write(&path, "MIS_TAKEOFF_ALT = 4.5\nNOT_A_PARAM = 1\n").unwrap();
        let loaded = ParamStore::load_keeping_bad(&quad(), &path, 1_764_669_000).unwrap();
        let aside = dir.join("params.bad-1764669000");
        assert_eq!(loaded.set_aside.as_deref(), Some(aside.as_path()));
        assert_eq!(
            fs::read_to_string(&aside).unwrap(),
            "MIS_TAKEOFF_ALT = 4.5\nNOT_A_PARAM = 1\n"
        );
        assert!(!path.exists(), "moved, not copied: the caller saves the store there");
        assert_eq!(loaded.store.get("MIS_TAKEOFF_ALT").unwrap().1, ParamValue::Real32(4.5));
        let last = loaded.warnings.last().unwrap();
        assert!(
            last.contains("params.bad-1764669000") && last.contains("do not read"),
            "{last}"
        );
        // the same second again: a new name, the first kept
        fs::write(&path, "").unwrap();
        let loaded = ParamStore::load_keeping_bad(&quad(), &path, 1_764_669_000).unwrap();
        assert_eq!(loaded.set_aside, Some(dir.join("params.bad-1764669000.1")));
        assert!(loaded.warnings.last().unwrap().contains("is empty"));
        assert_eq!(loaded.store, ParamStore::new(&quad()));
        // a good file (all at default: only comments) and no file stay where they are
        changed_store().save(&path).unwrap();
        let loaded = ParamStore::load_keeping_bad(&quad(), &path, 1).unwrap();
        assert!(loaded.set_aside.is_none() && loaded.warnings.is_empty());
        ParamStore::new(&quad()).save(&path).unwrap();
        assert!(
            ParamStore::load_keeping_bad(&quad(), &path, 1)
                .unwrap()
                .set_aside
                .is_none()
        );
        fs::remove_file(&path).unwrap();
        let loaded = ParamStore::load_keeping_bad(&quad(), &path, 1).unwrap();
        assert!(loaded.set_aside.is_none());
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 2);
        fs::remove_dir_all(&dir).unwrap();
    }
    use super::*;
    use crate::statefile::{scratch_dir as scratch, temp_path, write_atomic};

    fn quad() -> Airframe {
        Airframe::load("quad").unwrap()
    }

    fn changed_store() -> ParamStore {
        let mut s = ParamStore::new(&quad());
        s.set("MIS_TAKEOFF_ALT", ParamValue::Real32(5.0)).unwrap();
        s.set("EST_ORDER", ParamValue::Int32(7)).unwrap();
        s.set("EST_CUTOFF", ParamValue::Real32(0.1)).unwrap();
        s.set("SIM_FEXT_X", ParamValue::Real32(-0.3)).unwrap();
        s.set("COM_DISARM_LAND", ParamValue::Real32(-1.0)).unwrap();
        s
    }

    #[test]
    fn save_load_round_trip_and_text_is_valid_toml() {
        let dir = scratch("round-trip");
        let path = dir.join("params.toml");
        let s = changed_store();
        s.save(&path).unwrap();
        let (back, warnings) = ParamStore::load(&quad(), &path).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(back.iter().collect::<Vec<_>>(), s.iter().collect::<Vec<_>>());
        let text = fs::read_to_string(&path).unwrap();
        let table: toml::Table = text.parse().unwrap();
        assert_eq!(table["MIS_TAKEOFF_ALT"].as_float(), Some(5.0));
        assert_eq!(table["EST_ORDER"].as_integer(), Some(7));
        assert!(!table.contains_key("RTL_RETURN_ALT"), "defaults are commented out");
        assert!(text.contains("# RTL_RETURN_ALT = 30.0"));
        // no temporary file is left behind
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bad_lines_are_warnings_and_the_rest_is_kept() {
        let dir = scratch("bad-lines");
        let path = dir.join("params.toml");
        fs::write(
            &path,
            "MIS_TAKEOFF_ALT = 4.5\n\
             NOT_A_PARAM = 1\n\
             CTRL_TYPE = 7\n\
             EST_ORDER = 2.5\n\
             [table]\n\
             RTL_RETURN_ALT = nan\n\
             MPC_XY_CRUISE = fast\n\
             SIM_MASS = 1.8 # comment\n\
             EST_POLY = 1\n\
             EST_POLY = 0\n\
             \"CTRL_POS_SCALE\" = 2\n\
             COM_OF_LOSS_T = 0.5\n\
             MDL_MA",
        )
        .unwrap();
        let (s, warnings) = ParamStore::load(&quad(), &path).unwrap();
        assert_eq!(s.get("MIS_TAKEOFF_ALT").unwrap().1, ParamValue::Real32(4.5));
        assert_eq!(s.get("SIM_MASS").unwrap().1, ParamValue::Real32(1.8));
        assert_eq!(s.get("EST_POLY").unwrap().1, ParamValue::Int32(0));
        assert_eq!(s.get("CTRL_POS_SCALE").unwrap().1, ParamValue::Real32(2.0));
        assert_eq!(s.get("COM_OF_LOSS_T").unwrap().1, ParamValue::Real32(0.5));
        // refused lines kept their defaults
        assert_eq!(s.get("CTRL_TYPE").unwrap().1, ParamValue::Int32(1));
        assert_eq!(s.get("EST_ORDER").unwrap().1, ParamValue::Int32(3));
        assert_eq!(s.get("RTL_RETURN_ALT").unwrap().1, ParamValue::Real32(30.0));
        assert_eq!(s.get("MPC_XY_CRUISE").unwrap().1, ParamValue::Real32(5.0));
        assert_eq!(warnings.len(), 8, "{warnings:#?}");
        assert!(warnings[0].contains(":2:") && warnings[0].contains("NOT_A_PARAM"));
        assert!(warnings.iter().any(|w| w.contains("CTRL_TYPE = 7 is outside [0, 2]")));
        assert!(warnings.iter().any(|w| w.contains("given again")));
        assert!(warnings.iter().any(|w| w.contains(":13:")), "the truncated last line");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn missing_file_is_an_error_or_the_defaults() {
        let dir = scratch("missing");
        let path = dir.join("none.toml");
        assert!(matches!(
            ParamStore::load(&quad(), &path),
            Err(ParamFileError::Io { .. })
        ));
        let (s, w) = ParamStore::load_or_default(&quad(), &path).unwrap();
        assert_eq!(s, ParamStore::new(&quad()));
        assert!(w.is_empty());
        // non-UTF-8 bytes spoil one line only
        fs::write(&path, b"EST_ORDER = 5\nSIM_MASS = \xff\xfe\n").unwrap();
        let (s, w) = ParamStore::load(&quad(), &path).unwrap();
        assert_eq!(s.get("EST_ORDER").unwrap().1, ParamValue::Int32(5));
        assert_eq!(w.len(), 1);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn save_goes_through_a_synced_temp_file_and_rename() {
        let dir = scratch("temp-rename");
        let path = dir.join("params.toml");
        let tmp = temp_path(&path).unwrap();
        assert_eq!(tmp.parent(), path.parent(), "same directory: rename is atomic");
        let s = changed_store();
        // the writer sees the temporary file, not the target
        write_atomic(&path, s.to_file_text().as_bytes(), |f, b| {
            assert!(tmp.exists() && !path.exists());
            f.write_all(b)
        })
        .unwrap();
        assert!(path.exists() && !tmp.exists());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_write_failing_half_way_never_replaces_the_good_file() {
        let dir = scratch("crash");
        let path = dir.join("params.toml");
        let good = changed_store();
        good.save(&path).unwrap();
        let good_text = fs::read_to_string(&path).unwrap();

        let mut other = ParamStore::new(&quad());
        other.set("MIS_TAKEOFF_ALT", ParamValue::Real32(9.0)).unwrap();
        let text = other.to_file_text();
        let err = write_atomic(&path, text.as_bytes(), |f, b| {
            f.write_all(&b[..b.len() / 2])?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("disk full"));
        assert_eq!(fs::read_to_string(&path).unwrap(), good_text);
        assert!(!temp_path(&path).unwrap().exists(), "temp file removed");

        // A crash (no cleanup) leaves a truncated temp file: the target is
        // still the good one, loading ignores the temp, and the next save replaces it.
        let tmp = temp_path(&path).unwrap();
        fs::write(&tmp, &text.as_bytes()[..text.len() / 3]).unwrap();
        let (loaded, w) = ParamStore::load(&quad(), &path).unwrap();
        assert!(w.is_empty());
        assert_eq!(loaded.iter().collect::<Vec<_>>(), good.iter().collect::<Vec<_>>());
        other.save(&path).unwrap();
        assert!(!tmp.exists());
        let (loaded, _) = ParamStore::load(&quad(), &path).unwrap();
        assert_eq!(loaded.get("MIS_TAKEOFF_ALT").unwrap().1, ParamValue::Real32(9.0));
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unwritable_target_is_an_error_naming_the_path() {
        let dir = scratch("unwritable");
        // a directory in the way of the rename
        let path = dir.join("params.toml");
        fs::create_dir_all(path.join("inside")).unwrap();
        let err = ParamStore::new(&quad()).save(&path).unwrap_err();
        assert!(err.to_string().contains("params.toml"), "{err}");
        assert!(path.join("inside").exists());
        assert!(!temp_path(&path).unwrap().exists());
        assert!(matches!(
            ParamStore::new(&quad()).save(Path::new("/")),
            Err(ParamFileError::NotAFile(_))
        ));
        fs::remove_dir_all(&dir).unwrap();
    }
}
