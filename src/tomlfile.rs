//! Reading TOML files (airframes, scenarios) into typed values, with errors
//! that name the file, the line or field, and the problem.

/// Why a TOML file could not be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FileError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// Path as given.
        file: String,
        /// OS message.
        message: String,
    },
    /// Not valid TOML, or a key unknown, missing or of the wrong type.
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// Path or label.
        file: String,
        /// 1-based line of the offending text.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message, which names the key.
        message: String,
    },
    /// A value out of range or inconsistent with others.
    #[error("{file}: {field}: {problem}")]
    Invalid {
        /// Path or label.
        file: String,
        /// Dotted field name.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

impl FileError {
    /// An [`FileError::Invalid`].
    pub fn invalid(file: &str, field: impl Into<String>, problem: impl Into<String>) -> Self {
        FileError::Invalid {
            file: file.to_string(),
            field: field.into(),
            problem: problem.into(),
        }
    }
}

/// Read a file to text.
///
/// # Errors
/// [`FileError::Io`].
pub fn read(path: &std::path::Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|e| FileError::Io {
        file: path.display().to_string(),
        message: e.to_string(),
    })
}

/// Deserialize TOML text; `file` labels errors, which carry line and column.
///
/// # Errors
/// [`FileError::Syntax`].
pub fn parse<T: serde::de::DeserializeOwned>(text: &str, file: &str) -> Result<T, FileError> {
    toml::from_str(text).map_err(|e| {
        let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
        FileError::Syntax {
            file: file.to_string(),
            line,
            column,
            message: e.message().trim().to_string(),
        }
    })
}

/// A [`FileError::Syntax`] at byte `offset` of `text` (for problems found
/// after parsing, at a key whose span is known).
#[must_use]
pub fn error_at(text: &str, file: &str, offset: usize, message: String) -> FileError {
    let (line, column) = line_column(text, offset);
    FileError::Syntax {
        file: file.to_string(),
        line,
        column,
        message,
    }
}

/// Line and column (1-based) of a byte offset.
#[must_use]
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, str::len) + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_counts_from_one() {
        assert_eq!(line_column("a\nbc\nd", 3), (2, 2));
        assert_eq!(line_column("abc", 0), (1, 1));
    }

    #[test]
    fn syntax_errors_carry_the_position_and_the_key() {
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct T {
            a: f64,
        }
        let e = parse::<T>("a = 1.0\nb = 2\n", "t.toml").unwrap_err().to_string();
        assert!(e.starts_with("t.toml:2:1:") && e.contains("unknown field `b`"), "{e}");
    }
}
