//! The files of a map: the `map_server` YAML and its PGM or PNG image, read into [`MapMeta`] and
//! grey values.

use std::path::{Path, PathBuf};

use thiserror::Error;
use yaml_rust2::{Yaml, YamlLoader};

use super::Cell;

/// What went wrong loading a map. Every variant names the file.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum MapError {
    /// The file could not be read.
    #[error("{path}: cannot read: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error (in the message, so not a `source`: a chain of causes prints it once).
        error: std::io::Error,
    },
    /// The YAML does not parse, or is not a mapping.
    #[error("{path}: malformed YAML: {message}")]
    Yaml {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// A key is missing or has a bad value.
    #[error("{path}: {field}: {problem}")]
    Field {
        /// The file.
        path: PathBuf,
        /// The key.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// The image cannot be decoded.
    #[error("{path}: bad image: {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

/// How pixel values become occupancy (`mode` in the YAML).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum MapMode {
    /// Occupied, free or unknown by the thresholds (the default).
    Trinary,
    /// Like trinary for what the car cares about: anything between the thresholds is not free.
    Scale,
    /// The pixel value is the occupancy in percent.
    Raw,
}

/// The metadata of a map's YAML file.
#[derive(Clone, Debug, PartialEq)]
pub struct MapMeta {
    /// The image file, resolved against the YAML's folder.
    pub image: PathBuf,
    /// Metres per pixel.
    pub resolution: f64,
    /// Pose of the lower-left pixel's corner `(x, y, yaw)`.
    pub origin: [f64; 3],
    /// White is occupied.
    pub negate: bool,
    /// Occupancy probability above which a cell is occupied.
    pub occupied_thresh: f64,
    /// Occupancy probability below which a cell is free.
    pub free_thresh: f64,
    /// How pixel values are read.
    pub mode: MapMode,
}

fn field(path: &Path, field: &'static str, problem: impl Into<String>) -> MapError {
    MapError::Field {
        path: path.to_path_buf(),
        field,
        problem: problem.into(),
    }
}

fn number(y: &Yaml) -> Option<f64> {
    match y {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => y.as_f64(),
        _ => None,
    }
}

impl MapMeta {
    /// Parses the YAML text of a map; `path` is the YAML file (for messages and to resolve the
    /// image).
    pub fn parse(text: &str, path: &Path) -> Result<Self, MapError> {
        let docs = YamlLoader::load_from_str(text).map_err(|e| MapError::Yaml {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let doc = docs.first().ok_or_else(|| MapError::Yaml {
            path: path.to_path_buf(),
            message: "empty document".into(),
        })?;
        let hash = doc.as_hash().ok_or_else(|| MapError::Yaml {
            path: path.to_path_buf(),
            message: "expected a mapping of keys (image, resolution, origin, ...)".into(),
        })?;
        for key in hash.keys() {
            let known = matches!(
                key.as_str(),
                Some(
                    "image"
                        | "resolution"
                        | "origin"
                        | "negate"
                        | "occupied_thresh"
                        | "free_thresh"
                        | "mode"
                )
            );
            if !known {
                return Err(MapError::Yaml {
                    path: path.to_path_buf(),
                    message: format!("unknown key {key:?}"),
                });
            }
        }
        let get = |k: &str| {
            let v = &doc[k];
            (!v.is_badvalue()).then_some(v)
        };
        let image = get("image")
            .ok_or_else(|| field(path, "image", "missing"))?
            .as_str()
            .ok_or_else(|| field(path, "image", "must be a file name"))?;
        if image.is_empty() {
            return Err(field(path, "image", "must be a file name"));
        }
        let dir = path.parent().unwrap_or(Path::new(""));
        let image = dir.join(image);
        let resolution =
            number(get("resolution").ok_or_else(|| field(path, "resolution", "missing"))?)
                .ok_or_else(|| field(path, "resolution", "must be a number"))?;
        if !(resolution.is_finite() && resolution > 0.0 && resolution <= 10.0) {
            return Err(field(
                path,
                "resolution",
                format!("must be in (0, 10] m/px, got {resolution}"),
            ));
        }
        let origin_y = get("origin").ok_or_else(|| field(path, "origin", "missing"))?;
        let list = origin_y
            .as_vec()
            .filter(|v| v.len() == 3)
            .ok_or_else(|| field(path, "origin", "must be a list [x, y, yaw]"))?;
        let mut origin = [0.0; 3];
        for (o, y) in origin.iter_mut().zip(list) {
            *o = number(y)
                .filter(|x| x.is_finite() && x.abs() <= 1.0e6)
                .ok_or_else(|| field(path, "origin", "must hold three finite numbers"))?;
        }
        let negate = match get("negate") {
            None => false,
            Some(Yaml::Integer(0)) | Some(Yaml::Boolean(false)) => false,
            Some(Yaml::Integer(1)) | Some(Yaml::Boolean(true)) => true,
            Some(_) => return Err(field(path, "negate", "must be 0 or 1")),
        };
        let thresh = |k: &'static str, default: f64| -> Result<f64, MapError> {
            match get(k) {
                None => Ok(default),
                Some(y) => {
                    let v = number(y).ok_or_else(|| field(path, k, "must be a number"))?;
                    if (0.0..=1.0).contains(&v) {
                        Ok(v)
                    } else {
                        Err(field(path, k, format!("must be in [0, 1], got {v}")))
                    }
                }
            }
        };
        let occupied_thresh = thresh("occupied_thresh", 0.65)?;
        let free_thresh = thresh("free_thresh", 0.196)?;
        if free_thresh > occupied_thresh {
            return Err(field(
                path,
                "free_thresh",
                format!("must not exceed occupied_thresh ({free_thresh} > {occupied_thresh})"),
            ));
        }
        let mode = match get("mode").map(|m| m.as_str()) {
            None | Some(Some("trinary")) => MapMode::Trinary,
            Some(Some("scale")) => MapMode::Scale,
            Some(Some("raw")) => MapMode::Raw,
            Some(_) => return Err(field(path, "mode", "must be trinary, scale or raw")),
        };
        Ok(Self {
            image,
            resolution,
            origin,
            negate,
            occupied_thresh,
            free_thresh,
            mode,
        })
    }

    /// The cell a pixel of value `v` (0–255, mean of the colour channels) and alpha `alpha`
    /// (0–255) becomes.
    pub fn classify(&self, v: f64, alpha: f64) -> Cell {
        if alpha <= 0.0 {
            return Cell::Unknown;
        }
        if self.mode == MapMode::Raw {
            return if v < self.free_thresh * 100.0 {
                Cell::Free
            } else if (v - 100.0).abs() < 0.5 || v > self.occupied_thresh * 100.0 && v <= 100.0 {
                Cell::Occupied
            } else {
                Cell::Unknown
            };
        }
        let p = if self.negate {
            v / 255.0
        } else {
            (255.0 - v) / 255.0
        };
        if p > self.occupied_thresh {
            Cell::Occupied
        } else if p < self.free_thresh {
            Cell::Free
        } else {
            Cell::Unknown
        }
    }
}

/// A decoded image: grey values 0–255 and alpha 0–255, row 0 at the top.
pub(super) struct Grey {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) value: Vec<f64>,
    pub(super) alpha: Vec<f64>,
}

pub(super) fn image_err(path: &Path, message: impl Into<String>) -> MapError {
    MapError::Image {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Largest image side accepted (pixels).
pub const MAX_IMAGE_SIDE: usize = 20_000;

pub(super) fn decode_pgm(bytes: &[u8], path: &Path) -> Result<Grey, MapError> {
    // Header: magic, width, height, maxval, separated by whitespace, with '#' comments.
    let mut pos = 0usize;
    let token = |pos: &mut usize| -> Option<String> {
        loop {
            while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
                *pos += 1;
            }
            if *pos < bytes.len() && bytes[*pos] == b'#' {
                while *pos < bytes.len() && bytes[*pos] != b'\n' {
                    *pos += 1;
                }
                continue;
            }
            break;
        }
        let start = *pos;
        while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
            *pos += 1;
        }
        (start < *pos).then(|| String::from_utf8_lossy(&bytes[start..*pos]).into_owned())
    };
    let magic = token(&mut pos).ok_or_else(|| image_err(path, "empty PGM"))?;
    let binary = match magic.as_str() {
        "P5" => true,
        "P2" => false,
        m => {
            return Err(image_err(
                path,
                format!("not a PGM (magic {m:?}, expected P5 or P2)"),
            ));
        }
    };
    let num = |what: &str, pos: &mut usize| -> Result<usize, MapError> {
        token(pos)
            .and_then(|t| t.parse::<usize>().ok())
            .ok_or_else(|| image_err(path, format!("PGM header: bad {what}")))
    };
    let width = num("width", &mut pos)?;
    let height = num("height", &mut pos)?;
    let maxval = num("maxval", &mut pos)?;
    check_size(width, height, path)?;
    if maxval == 0 || maxval > 65_535 {
        return Err(image_err(
            path,
            format!("PGM maxval {maxval} not in 1..=65535"),
        ));
    }
    let n = width * height;
    let scale = 255.0 / maxval as f64;
    let mut value = Vec::new();
    if binary {
        pos += 1; // the single whitespace after maxval
        let wide = maxval > 255;
        let need = n * if wide { 2 } else { 1 };
        // Check the length before allocating anything the header asks for.
        let data = bytes
            .get(pos..pos + need)
            .ok_or_else(|| image_err(path, format!("PGM data truncated: need {need} bytes")))?;
        value.reserve_exact(n);
        if wide {
            value.extend(
                data.chunks_exact(2)
                    .map(|c| u16::from_be_bytes([c[0], c[1]]) as f64 * scale),
            );
        } else {
            value.extend(data.iter().map(|&b| b as f64 * scale));
        }
    } else {
        // Every ASCII pixel takes at least one byte.
        if bytes.len().saturating_sub(pos) < n {
            return Err(image_err(
                path,
                format!("PGM data truncated: need {n} pixels"),
            ));
        }
        value.reserve_exact(n);
        for _ in 0..n {
            let v = num("pixel", &mut pos)?;
            if v > maxval {
                return Err(image_err(path, format!("pixel {v} above maxval {maxval}")));
            }
            value.push(v as f64 * scale);
        }
    }
    Ok(Grey {
        width,
        height,
        value,
        alpha: vec![255.0; n],
    })
}

fn check_size(width: usize, height: usize, path: &Path) -> Result<(), MapError> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(image_err(
            path,
            format!("size {width}×{height} not within 1..={MAX_IMAGE_SIDE} per side"),
        ));
    }
    Ok(())
}

pub(super) fn decode_png(bytes: &[u8], path: &Path) -> Result<Grey, MapError> {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder
        .read_info()
        .map_err(|e| image_err(path, format!("PNG: {e}")))?;
    let (width, height) = {
        let info = reader.info();
        (info.width as usize, info.height as usize)
    };
    check_size(width, height, path)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| image_err(path, "PNG too large"))?;
    let mut buf = vec![0u8; size];
    let frame = reader
        .next_frame(&mut buf)
        .map_err(|e| image_err(path, format!("PNG: {e}")))?;
    let channels = frame.color_type.samples();
    let n = width * height;
    let mut value = Vec::with_capacity(n);
    let mut alpha = Vec::with_capacity(n);
    for r in 0..height {
        let row = &buf[r * frame.line_size..r * frame.line_size + width * channels];
        for px in row.chunks_exact(channels) {
            let (colour, a) = match channels {
                1 => (&px[..1], 255.0),
                2 => (&px[..1], px[1] as f64),
                3 => (&px[..3], 255.0),
                _ => (&px[..3], px[3] as f64),
            };
            let mean = colour.iter().map(|&c| c as f64).sum::<f64>() / colour.len() as f64;
            value.push(mean);
            alpha.push(a);
        }
    }
    Ok(Grey {
        width,
        height,
        value,
        alpha,
    })
}
