//! The one error type of septa.
//!
//! Every failure that a user can cause (a bad file, a bad config, an impossible
//! parameter) is an [`Error`] whose message names the problem and, where there is
//! one, the file. Nothing in the library panics on bad input.

use std::path::{Path, PathBuf};

/// Result alias used throughout septa.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong, with enough context to act on it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file was read but its content is not acceptable.
    #[error("{}: {problem}", path.display())]
    Input { path: PathBuf, problem: String },
    /// A configuration file is wrong; `key` points at the offending entry.
    #[error("{}: {key}: {problem}", path.display())]
    Config {
        path: PathBuf,
        key: String,
        problem: String,
    },
    /// A parameter given to the library or on the command line is wrong.
    #[error("{0}")]
    Invalid(String),
    /// A named parameter (`name`, as the library calls it) is out of its
    /// bounds; callers that know where it came from (a flag, a config key)
    /// say so instead.
    #[error("{name} = {value}: {problem}")]
    Parameter {
        name: &'static str,
        value: String,
        problem: String,
    },
}

impl Error {
    /// A problem with the content of `path`.
    pub fn input(path: impl AsRef<Path>, problem: impl Into<String>) -> Self {
        Error::Input {
            path: path.as_ref().to_path_buf(),
            problem: problem.into(),
        }
    }

    /// An I/O failure on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// A wrong entry `key` in the config file `path`.
    pub fn config(
        path: impl AsRef<Path>,
        key: impl Into<String>,
        problem: impl Into<String>,
    ) -> Self {
        Error::Config {
            path: path.as_ref().to_path_buf(),
            key: key.into(),
            problem: problem.into(),
        }
    }

    /// A wrong parameter.
    pub fn invalid(problem: impl Into<String>) -> Self {
        Error::Invalid(problem.into())
    }

    /// Parameter `name` has the out-of-bounds `value`.
    pub fn parameter(name: &'static str, value: impl ToString, problem: impl Into<String>) -> Self {
        Error::Parameter {
            name,
            value: value.to_string(),
            problem: problem.into(),
        }
    }
}
