//! The report's files: written with their folders, read with the file named in every error,
//! and CSV through the `csv` crate.
//!
//! Numbers are formatted by the caller (`{:.6}` for the report's tables, Rust's shortest
//! round-trip `{}` for a shard's raw results) and written as text fields, so the bytes are the
//! caller's choice; reading parses them back with `str::parse`, exactly.

use std::path::Path;

use anyhow::{Context, Result};
use serde::de::DeserializeOwned;

/// Writes `bytes` to `path`, creating its folder.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    std::fs::write(path, bytes).with_context(|| format!("{}: cannot write", path.display()))
}

/// The text of `path`.
pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// A CSV file's bytes: `header`, then one record per row of formatted fields.
pub fn csv_bytes<I, R>(header: &[&str], rows: I) -> Result<Vec<u8>>
where
    I: IntoIterator<Item = R>,
    R: IntoIterator,
    R::Item: AsRef<[u8]>,
{
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header)?;
    for row in rows {
        w.write_record(row)?;
    }
    w.into_inner().context("csv: cannot finish")
}

/// Writes a CSV file ([`csv_bytes`]) to `path`, creating its folder.
pub fn write_csv<I, R>(path: &Path, header: &[&str], rows: I) -> Result<()>
where
    I: IntoIterator<Item = R>,
    R: IntoIterator,
    R::Item: AsRef<[u8]>,
{
    write_file(path, &csv_bytes(header, rows)?)
}

/// The rows of the CSV file `path`, each deserialized by its header's names.
pub fn read_csv<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("{}: cannot read", path.display()))?;
    r.deserialize()
        .map(|row| row.with_context(|| format!("{}: bad row", path.display())))
        .collect()
}
