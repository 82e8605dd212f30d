//! Errors of the UFF reader and writer. Every error names the file (as the caller
//! passed it), and where it can the dataset (1-based index in the file, its number and
//! the line it starts on) and the record/field.

use thiserror::Error;

/// Where in a file a dataset sits: used by every dataset-level error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatasetLocation {
    /// 1-based position of the dataset in the file.
    pub index: usize,
    /// Dataset number (58, 2411, …).
    pub number: i64,
    /// 1-based line of the dataset's opening `-1` delimiter.
    pub line: usize,
}

impl std::fmt::Display for DatasetLocation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "dataset #{} (type {}, starting at line {})",
            self.index, self.number, self.line
        )
    }
}

/// Why a universal file could not be read or written. Each reading error names the file and, where known, the dataset and field.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum UffError {
    /// A malformed or unsupported field inside one dataset.
    #[error("{file}: {at}: {field}: {problem}")]
    Field {
        /// The file's name as the caller gave it.
        file: String,
        /// Which dataset.
        at: DatasetLocation,
        /// Record and field, e.g. "record 7 field 2 (number of values)" or "line 31 value 3".
        field: String,
        /// What is wrong with the field.
        problem: String,
    },
    /// A problem with the file structure outside any one dataset (delimiters, truncation).
    #[error("{file}: line {line}: {problem}")]
    Structure {
        /// The file's name as the caller gave it.
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// The datasets are individually valid but do not form one campaign
    /// (abscissae differ, a combination is missing, …).
    #[error("{file}: {problem}")]
    Campaign {
        /// The file's name as the caller gave it.
        file: String,
        /// What does not fit.
        problem: String,
    },
    /// The writer was given an inconsistent geometry / FRF set.
    #[error("cannot write UFF: {0}")]
    Write(String),
}
