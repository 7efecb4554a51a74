//! Image file I/O for furnace: multi-channel linear OpenEXR and 8-bit sRGB PNG previews.
//! [`write_exr`] / [`read_exr`] store a [`Layers`] image (named `f32` channels plus string
//! metadata) losslessly and bit-exactly; [`write_png_srgb`] writes an exposure-scaled, clamped,
//! sRGB-encoded preview. Units: pixel values are never interpreted (radiance, XYZ, variances,
//! sample counts, … as the caller stores them); only the PNG assumes linear-light sRGB. Bad
//! input is an [`ImageIoError`], never a panic. Compression, channel names and order, and
//! robustness: docs/formats.md, "`io::image`".

use std::collections::HashSet;
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
use exr::meta::attribute::{AttributeValue, LineOrder, Text};
use exr::meta::header::{standard_names, LayerAttributes};
use exr::prelude::traits::{ReadChannels as _, ReadLayers as _, WritableImage as _};
use exr::prelude::SmallVec;

/// A multi-channel image: named f32 channels of width*height values each, row-major,
/// top row first.
///
/// Pixel `(x, y)` of a channel is at index `y * width + x`, with `y = 0` the top row.
/// Values are linear and unit-less as far as this module is concerned: they are whatever the
/// caller stores (radiance, XYZ, variance, ...), and are written and read back bit-exactly.
///
/// `attributes` are free-form `(name, value)` string metadata stored in the EXR header.
#[derive(Debug, Clone, PartialEq)]
pub struct Layers {
    /// Width in pixels (at least 1 for [`write_exr`]).
    pub width: usize,
    /// Height in pixels (at least 1 for [`write_exr`]).
    pub height: usize,
    /// `(name, values)` pairs; each `values` holds `width * height` samples, row-major,
    /// top row first. Names must be non-empty and unique.
    pub channels: Vec<(String, Vec<f32>)>,
    /// `(name, value)` string attributes of the EXR header. Names must be unique.
    pub attributes: Vec<(String, String)>,
}

impl Layers {
    /// The samples of the channel called exactly `name` (e.g. `"variance.Y"`), or `None` if
    /// there is no such channel.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels
            .iter()
            .find(|(channel_name, _)| channel_name == name)
            .map(|(_, values)| values.as_slice())
    }
}

/// Everything that can go wrong reading or writing images. Every variant names the file
/// involved and says what was expected.
#[derive(Debug, thiserror::Error)]
pub enum ImageIoError {
    /// The file system refused an operation (missing file, permissions, full disk, ...).
    #[error("I/O error on `{path}`: {source}")]
    Io {
        /// The file (or parent directory) involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// The `exr` crate rejected the file (not an OpenEXR file, corrupt, or using an
    /// unsupported feature such as deep data) or could not encode the image.
    #[error(
        "OpenEXR error for `{path}`: {source} (only flat, non-deep OpenEXR images are supported)"
    )]
    Exr {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: exr::error::Error,
    },

    /// The `png` crate could not encode the preview.
    #[error("PNG encoding error for `{path}`: {source}")]
    Png {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: png::EncodingError,
    },

    /// The EXR decoder panicked on this file; it is treated as corrupt.
    #[error("OpenEXR decoder failed on `{path}` (file is probably corrupt): {message}")]
    DecoderPanic {
        /// The file involved.
        path: PathBuf,
        /// The panic message, if it was a string.
        message: String,
    },

    /// Width or height is unusable.
    #[error("invalid image size {width}x{height} for `{path}`: {reason}")]
    InvalidSize {
        /// The file involved.
        path: PathBuf,
        /// The requested width.
        width: usize,
        /// The requested height.
        height: usize,
        /// What is allowed.
        reason: &'static str,
    },

    /// An EXR image needs at least one channel.
    #[error("image for `{path}` has no channels: an OpenEXR image needs at least one channel")]
    NoChannels {
        /// The file involved.
        path: PathBuf,
    },

    /// A channel does not hold exactly `width * height` values.
    #[error(
        "channel `{channel}` of `{path}` has {found} values, expected {expected} \
         (width * height, one f32 per pixel)"
    )]
    ChannelLength {
        /// The file involved.
        path: PathBuf,
        /// The channel name.
        channel: String,
        /// `width * height`.
        expected: usize,
        /// The actual number of values.
        found: usize,
    },

    /// A channel name is empty, contains NUL, or is too long.
    #[error("invalid channel name {channel:?} for `{path}`: {reason}")]
    InvalidChannelName {
        /// The file involved.
        path: PathBuf,
        /// The offending name.
        channel: String,
        /// What is allowed.
        reason: &'static str,
    },

    /// Two channels have the same name.
    #[error("duplicate channel name `{channel}` in `{path}`: channel names must be unique")]
    DuplicateChannel {
        /// The file involved.
        path: PathBuf,
        /// The repeated name.
        channel: String,
    },

    /// An attribute name is invalid, repeated, or reserved by OpenEXR (structural or non-string attributes).
    #[error("invalid attribute {name:?} for `{path}`: {reason}")]
    InvalidAttribute {
        /// The file involved.
        path: PathBuf,
        /// The offending attribute name.
        name: String,
        /// What is wrong and what is allowed.
        reason: String,
    },

    /// The PNG pixel buffer does not hold exactly `width * height` pixels.
    #[error(
        "pixel buffer for `{path}` has {found} pixels, expected {expected} ({width}x{height})"
    )]
    PixelCount {
        /// The file involved.
        path: PathBuf,
        /// The requested width.
        width: usize,
        /// The requested height.
        height: usize,
        /// `width * height`.
        expected: usize,
        /// The actual number of pixels.
        found: usize,
    },

    /// The PNG exposure multiplier is NaN, infinite or negative.
    #[error("invalid exposure {exposure} for `{path}`: exposure must be finite and >= 0")]
    InvalidExposure {
        /// The file involved.
        path: PathBuf,
        /// The offending exposure.
        exposure: f64,
    },
}

/// Longest channel or attribute name OpenEXR allows, in bytes.
const MAX_NAME_BYTES: usize = 255;

/// String attributes that OpenEXR defines with standard names; the `exr` crate keeps them in
/// dedicated [`LayerAttributes`] fields instead of `other`. Every other standard name is reserved
/// for a structural or non-string attribute (e.g. `channels`, `name`, `expTime`).
const STANDARD_STRING_ATTRIBUTES: [&str; 8] = [
    "capDate",
    "comments",
    "lookModTransform",
    "owner",
    "renderingTransform",
    "software",
    "view",
    "wrapmodes",
];

/// The dedicated string fields of [`LayerAttributes`], in the order of
/// [`STANDARD_STRING_ATTRIBUTES`].
fn standard_string_fields(attributes: &mut LayerAttributes) -> [&mut Option<Text>; 8] {
    [
        &mut attributes.capture_date,
        &mut attributes.comments,
        &mut attributes.look_modification_transform_name,
        &mut attributes.owner,
        &mut attributes.rendering_transform_name,
        &mut attributes.software_name,
        &mut attributes.view_name,
        &mut attributes.wrap_mode_name,
    ]
}

/// Write `image` as a single-part, scan-line OpenEXR file with 32-bit float channels and
/// lossless run-length (RLE) compression: a render's noisy floats barely deflate, so ZIP's
/// files were 2-5 % smaller for about ten times the encoding time (docs/performance.md, "EXR
/// files run-length encoded").
///
/// Values are stored bit-exactly; units are whatever the caller stores. Channels may be given
/// in any order (OpenEXR stores them sorted by name). `image.attributes` become string
/// attributes of the header; standard OpenEXR string attributes (`owner`, `comments`,
/// `capDate`, `software`, `view`, `renderingTransform`, `lookModTransform`, `wrapmodes`) are
/// allowed, other standard names (e.g. `channels`, `name`, `expTime`) are reserved.
/// Parent directories of `path` are created if missing; an existing file is replaced.
///
/// # Errors
/// * [`ImageIoError::InvalidSize`]: width or height is 0, or larger than OpenEXR allows.
/// * [`ImageIoError::NoChannels`], [`ImageIoError::ChannelLength`] (a channel does not have
///   `width * height` values), [`ImageIoError::InvalidChannelName`] (empty, contains NUL, or
///   longer than 255 bytes), [`ImageIoError::DuplicateChannel`].
/// * [`ImageIoError::InvalidAttribute`]: empty / NUL / over-long / duplicate / reserved name.
/// * [`ImageIoError::Io`] or [`ImageIoError::Exr`] if writing fails.
pub fn write_exr(path: &Path, image: &Layers) -> Result<(), ImageIoError> {
    write_exr_owned(path, image.clone())
}

/// [`write_exr`] for an image the caller no longer needs: its channels are written without a
/// copy (a 1024² film's twelve channels are 48 MiB).
pub fn write_exr_owned(path: &Path, image: Layers) -> Result<(), ImageIoError> {
    let layer_attributes = check_layers(path, &image)?;
    let size = (image.width, image.height);
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = image
        .channels
        .into_iter()
        .map(|(name, values)| AnyChannel::new(to_text(&name), FlatSamples::F32(values)))
        .collect();
    let encoding = Encoding {
        compression: exr::compression::Compression::RLE,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        size,
        layer_attributes,
        encoding,
        AnyChannels::sort(channels),
    );

    create_parent_dirs(path)?;
    let image = Image::from_layer(layer);
    let mut failure = None;
    super::located::write_atomic(path, |tmp| {
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write().to_buffered(&mut bytes).map_err(|e| {
            failure = Some(e);
            std::io::Error::other("EXR write failed")
        })?;
        let mut bytes = bytes.into_inner();
        sort_header_attributes(&mut bytes);
        fs::write(tmp, &bytes)
    })
    .map_err(|source| match failure.take() {
        Some(e) => exr_error(path, e),
        None => io_error(path, source),
    })
}

/// The errors [`write_exr`] lists, and the layer's attributes.
fn check_layers(path: &Path, image: &Layers) -> Result<LayerAttributes, ImageIoError> {
    let pixel_count = exr_pixel_count(path, image.width, image.height)?;

    if image.channels.is_empty() {
        return Err(ImageIoError::NoChannels {
            path: path.to_path_buf(),
        });
    }

    let mut seen_channels = HashSet::with_capacity(image.channels.len());
    for (name, values) in &image.channels {
        check_name(name).map_err(|reason| ImageIoError::InvalidChannelName {
            path: path.to_path_buf(),
            channel: name.clone(),
            reason,
        })?;
        if !seen_channels.insert(name.as_str()) {
            return Err(ImageIoError::DuplicateChannel {
                path: path.to_path_buf(),
                channel: name.clone(),
            });
        }
        if values.len() != pixel_count {
            return Err(ImageIoError::ChannelLength {
                path: path.to_path_buf(),
                channel: name.clone(),
                expected: pixel_count,
                found: values.len(),
            });
        }
    }

    exr_layer_attributes(path, &image.attributes)
}

/// Puts the header attributes of a single-part OpenEXR file (`bytes`, as the `exr` crate wrote
/// it) in order of name, as the OpenEXR library writes them: `exr` keeps the free-form ones in a
/// `HashMap` and writes them in its iteration order, which changes from run to run, so the
/// same image would give different files. The header keeps its length, so the chunk offsets
/// after it stay valid. Multi-part and deep files, and anything that does not parse, are left
/// as they are.
fn sort_header_attributes(bytes: &mut [u8]) {
    const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
    const MULTIPART_OR_DEEP: u32 = 0x1000 | 0x800;
    if bytes.len() < 8 || bytes[..4] != MAGIC {
        return;
    }
    if u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) & MULTIPART_OR_DEEP != 0 {
        return;
    }
    // each attribute: name NUL, type NUL, size (i32 LE), value; an empty name ends the header
    let c_string_end = |from: usize| bytes[from..].iter().position(|&b| b == 0).map(|k| from + k);
    let mut spans = Vec::new();
    let mut at = 8;
    let end = loop {
        let Some(name_end) = c_string_end(at) else {
            return;
        };
        if name_end == at {
            break at;
        }
        let Some(type_end) = c_string_end(name_end + 1) else {
            return;
        };
        let Some(size) = bytes.get(type_end + 1..type_end + 5) else {
            return;
        };
        let size = i32::from_le_bytes([size[0], size[1], size[2], size[3]]);
        let Ok(size) = usize::try_from(size) else {
            return;
        };
        let next = type_end + 5 + size;
        if next > bytes.len() {
            return;
        }
        spans.push((at, name_end, next));
        at = next;
    };
    spans.sort_by(|a, b| bytes[a.0..a.1].cmp(&bytes[b.0..b.1]));
    let header: Vec<u8> = spans
        .iter()
        .flat_map(|&(start, _, next)| bytes[start..next].iter().copied())
        .collect();
    bytes[8..end].copy_from_slice(&header);
}

/// Read the first layer (part) of an OpenEXR file.
///
/// All channels are returned as `f32` (half values converted exactly; `u32` values converted
/// with `as f32`, which rounds above 2^24), in the on-disk order, with their names exactly as
/// stored (`"variance.Y"` stays `"variance.Y"`). `width`/`height` are the size of the data
/// window at the largest resolution level (its offset within the display window is not
/// reported). String attributes of the header end up in `attributes`, sorted by name; other
/// attribute types, and the structural part `name`/`type`, are skipped. Names and strings are
/// decoded as UTF-8, falling back to Latin-1 for bytes that are not valid UTF-8.
///
/// # Errors
/// * [`ImageIoError::Io`]: the file cannot be opened or read (e.g. it does not exist).
/// * [`ImageIoError::Exr`]: not an OpenEXR file, corrupt, or deep data.
/// * [`ImageIoError::DecoderPanic`]: the decoder panicked on a corrupt file.
/// * [`ImageIoError::ChannelLength`]: a channel is subsampled (unsupported) or truncated.
/// * [`ImageIoError::DuplicateChannel`]: the file repeats a channel name.
pub fn read_exr(path: &Path) -> Result<Layers, ImageIoError> {
    // The header first: a data window larger than the film limit, or more channels than any
    // image furnace reads, is refused before any pixel is allocated; so is a file that is not
    // a regular file (a FIFO would block).
    let meta = fs::metadata(path).map_err(|source| io_error(path, source))?;
    if !meta.is_file() {
        return Err(io_error(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a regular file"),
        ));
    }
    let header = std::panic::catch_unwind(|| exr::meta::MetaData::read_from_file(path, false));
    if let Ok(Ok(header)) = header {
        for h in &header.headers {
            let (w, hh) = (h.layer_size.width(), h.layer_size.height());
            if crate::limits::image(w as u64, hh as u64).is_err()
                || h.channels.list.len() > crate::limits::MAX_CHANNELS
            {
                return Err(ImageIoError::InvalidSize {
                    path: path.to_path_buf(),
                    width: w,
                    height: hh,
                    reason: "over furnace's image limit (65536 per side, 2^24 pixels, 64 channels): refused before decoding",
                });
            }
        }
    }
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        exr::image::read::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_file(path)
    }));
    let image = match decoded {
        Ok(Ok(image)) => image,
        Ok(Err(source)) => return Err(exr_error(path, source)),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|message| (*message).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_owned());
            return Err(ImageIoError::DecoderPanic {
                path: path.to_path_buf(),
                message,
            });
        }
    };

    let mut layer = image.layer_data;
    let width = layer.size.width();
    let height = layer.size.height();
    let expected = width.checked_mul(height).ok_or(ImageIoError::InvalidSize {
        path: path.to_path_buf(),
        width,
        height,
        reason: "width * height overflows usize",
    })?;

    let mut channels = Vec::with_capacity(layer.channel_data.list.len());
    let mut seen_channels = HashSet::with_capacity(layer.channel_data.list.len());
    for channel in layer.channel_data.list {
        let name = from_text(&channel.name);
        if !seen_channels.insert(name.clone()) {
            return Err(ImageIoError::DuplicateChannel {
                path: path.to_path_buf(),
                channel: name,
            });
        }
        let values: Vec<f32> = match channel.sample_data {
            FlatSamples::F32(values) => values,
            FlatSamples::F16(values) => values.iter().map(|value| value.to_f32()).collect(),
            #[allow(clippy::cast_precision_loss)] // documented: u32 -> f32 rounds above 2^24
            FlatSamples::U32(values) => values.iter().map(|&value| value as f32).collect(),
        };
        if values.len() != expected {
            return Err(ImageIoError::ChannelLength {
                path: path.to_path_buf(),
                channel: name,
                expected,
                found: values.len(),
            });
        }
        channels.push((name, values));
    }

    let mut attributes: Vec<(String, String)> = Vec::new();
    for (name, field) in STANDARD_STRING_ATTRIBUTES
        .iter()
        .zip(standard_string_fields(&mut layer.attributes))
    {
        if let Some(text) = field {
            attributes.push(((*name).to_owned(), from_text(text)));
        }
    }
    let custom = layer
        .attributes
        .other
        .iter()
        .chain(image.attributes.other.iter());
    for (name, value) in custom {
        if let AttributeValue::Text(text) = value {
            attributes.push((from_text(name), from_text(text)));
        }
    }
    attributes.sort();

    Ok(Layers {
        width,
        height,
        channels,
        attributes,
    })
}

/// Write an 8-bit sRGB RGB PNG preview of a linear RGB image.
///
/// `linear_rgb` holds `width * height` pixels, row-major, top row first, in linear-light
/// sRGB/Rec.709 primaries (any scale; units are whatever the caller stores). Each component is
/// multiplied by `exposure`, clamped to `[0, 1]`, encoded with the sRGB transfer function and
/// rounded to 8 bits. The file is tagged with an sRGB chunk.
///
/// **NaN pixels are written as magenta `(255, 0, 255)`** so that they stand out: a pixel is
/// treated as NaN if any component is NaN after exposure scaling (this includes `±inf * 0`).
/// Infinities otherwise clamp to 0 or 255.
///
/// Parent directories of `path` are created if missing; an existing file is replaced.
///
/// # Errors
/// * [`ImageIoError::InvalidSize`]: width or height is 0 or larger than PNG allows.
/// * [`ImageIoError::PixelCount`]: `linear_rgb.len() != width * height`.
/// * [`ImageIoError::InvalidExposure`]: `exposure` is NaN, infinite or negative.
/// * [`ImageIoError::Png`] or [`ImageIoError::Io`] if encoding or writing fails.
pub fn write_png_srgb(
    path: &Path,
    width: usize,
    height: usize,
    linear_rgb: &[[f64; 3]],
    exposure: f64,
) -> Result<(), ImageIoError> {
    let encoded = encode_png(path, width, height, linear_rgb, exposure)?;
    create_parent_dirs(path)?;
    super::located::write_atomic(path, |tmp| fs::write(tmp, &encoded))
        .map_err(|source| io_error(path, source))
}

/// The PNG file [`write_png_srgb`] would write, in memory (for self-contained HTML reports);
/// errors name the in-memory image as `<in-memory PNG>`.
pub fn encode_png_srgb(
    width: usize,
    height: usize,
    linear_rgb: &[[f64; 3]],
    exposure: f64,
) -> Result<Vec<u8>, ImageIoError> {
    encode_png(
        Path::new("<in-memory PNG>"),
        width,
        height,
        linear_rgb,
        exposure,
    )
}

fn encode_png(
    path: &Path,
    width: usize,
    height: usize,
    linear_rgb: &[[f64; 3]],
    exposure: f64,
) -> Result<Vec<u8>, ImageIoError> {
    const PNG_MAX_DIMENSION: usize = i32::MAX as usize; // PNG spec: at most 2^31 - 1
    let invalid_size = |reason| ImageIoError::InvalidSize {
        path: path.to_path_buf(),
        width,
        height,
        reason,
    };
    if width == 0 || height == 0 {
        return Err(invalid_size("width and height must both be at least 1"));
    }
    if width > PNG_MAX_DIMENSION || height > PNG_MAX_DIMENSION {
        return Err(invalid_size(
            "PNG width and height must be at most 2147483647",
        ));
    }
    let expected = width
        .checked_mul(height)
        .filter(|count| count.checked_mul(3).is_some())
        .ok_or_else(|| invalid_size("width * height * 3 bytes overflows usize"))?;
    if linear_rgb.len() != expected {
        return Err(ImageIoError::PixelCount {
            path: path.to_path_buf(),
            width,
            height,
            expected,
            found: linear_rgb.len(),
        });
    }
    if !exposure.is_finite() || exposure < 0.0 {
        return Err(ImageIoError::InvalidExposure {
            path: path.to_path_buf(),
            exposure,
        });
    }

    let mut bytes = Vec::with_capacity(expected * 3);
    for pixel in linear_rgb {
        let scaled = pixel.map(|component| component * exposure);
        if scaled.iter().any(|component| component.is_nan()) {
            bytes.extend_from_slice(&[255, 0, 255]);
        } else {
            bytes.extend(scaled.iter().map(|&component| encode_srgb_8bit(component)));
        }
    }

    // Dimensions were checked against i32::MAX above, so these conversions cannot fail.
    let png_width = u32::try_from(width).map_err(|_| invalid_size("width does not fit in u32"))?;
    let png_height =
        u32::try_from(height).map_err(|_| invalid_size("height does not fit in u32"))?;
    let png_error = |source| ImageIoError::Png {
        path: path.to_path_buf(),
        source,
    };

    let mut encoded = Vec::new();
    let mut encoder = png::Encoder::new(&mut encoded, png_width, png_height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer.write_image_data(&bytes).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(encoded)
}

/// Clamp a linear value to [0, 1], apply the sRGB transfer function and round to 8 bits.
/// `linear` must not be NaN (NaN is handled by the caller).
fn encode_srgb_8bit(linear: f64) -> u8 {
    let x = linear.clamp(0.0, 1.0);
    // sRGB OETF, IEC 61966-2-1: 12.92 x for x <= 0.0031308, else 1.055 x^(1/2.4) - 0.055
    let encoded = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    // `encoded` is in [0, 1], so the rounded value is in [0, 255] and the cast is exact.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let byte = (encoded * 255.0).round().clamp(0.0, 255.0) as u8;
    byte
}

/// Validate EXR dimensions and return `width * height`.
fn exr_pixel_count(path: &Path, width: usize, height: usize) -> Result<usize, ImageIoError> {
    const EXR_MAX_DIMENSION: usize = i32::MAX as usize; // pixel coordinates are i32
    let invalid_size = |reason| ImageIoError::InvalidSize {
        path: path.to_path_buf(),
        width,
        height,
        reason,
    };
    if width == 0 || height == 0 {
        return Err(invalid_size("width and height must both be at least 1"));
    }
    if width > EXR_MAX_DIMENSION || height > EXR_MAX_DIMENSION {
        return Err(invalid_size(
            "OpenEXR width and height must be at most 2147483647",
        ));
    }
    width
        .checked_mul(height)
        .ok_or_else(|| invalid_size("width * height overflows usize"))
}

/// Check a channel or attribute name; the error says what is allowed.
fn check_name(name: &str) -> Result<(), &'static str> {
    if name.is_empty() {
        Err("names must not be empty")
    } else if name.contains('\0') {
        Err("names must not contain NUL characters")
    } else if name.len() > MAX_NAME_BYTES {
        Err("names must be at most 255 bytes long (UTF-8)")
    } else {
        Ok(())
    }
}

/// Build the EXR layer attributes from the caller's string attributes.
fn exr_layer_attributes(
    path: &Path,
    attributes: &[(String, String)],
) -> Result<LayerAttributes, ImageIoError> {
    let invalid = |name: &str, reason: String| ImageIoError::InvalidAttribute {
        path: path.to_path_buf(),
        name: name.to_owned(),
        reason,
    };

    let mut layer_attributes = LayerAttributes::default();
    let mut seen = HashSet::with_capacity(attributes.len());
    for (name, value) in attributes {
        check_name(name).map_err(|reason| invalid(name, reason.to_owned()))?;
        if !seen.insert(name.as_str()) {
            return Err(invalid(name, "attribute names must be unique".to_owned()));
        }

        if let Some(index) = STANDARD_STRING_ATTRIBUTES
            .iter()
            .position(|standard| standard == name)
        {
            *standard_string_fields(&mut layer_attributes)[index] = Some(to_text(value));
        } else if standard_names::ALL.contains(&name.as_bytes()) {
            let mut reason = String::from(
                "this name is reserved by OpenEXR for a structural or non-string attribute; use \
                 another name (the standard string attributes allowed here are:",
            );
            for standard in STANDARD_STRING_ATTRIBUTES {
                let _ = write!(reason, " {standard}");
            }
            reason.push(')');
            return Err(invalid(name, reason));
        } else {
            layer_attributes
                .other
                .insert(to_text(name), AttributeValue::Text(to_text(value)));
        }
    }
    Ok(layer_attributes)
}

/// Store a string as UTF-8 bytes (the `exr` crate's `From<&str>` would panic on characters
/// outside Latin-1).
fn to_text(string: &str) -> Text {
    Text::from_slice_unchecked(string.as_bytes())
}

/// Decode EXR text as UTF-8, falling back to Latin-1 (one byte per character).
fn from_text(text: &Text) -> String {
    match std::str::from_utf8(text.as_slice()) {
        Ok(string) => string.to_owned(),
        Err(_) => text
            .as_slice()
            .iter()
            .map(|&byte| char::from(byte))
            .collect(),
    }
}

fn create_parent_dirs(path: &Path) -> Result<(), ImageIoError> {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => {
            fs::create_dir_all(parent).map_err(|source| io_error(parent, source))
        }
        _ => Ok(()),
    }
}

fn io_error(path: &Path, source: std::io::Error) -> ImageIoError {
    ImageIoError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Map an `exr` error, surfacing file-system errors as [`ImageIoError::Io`].
fn exr_error(path: &Path, source: exr::error::Error) -> ImageIoError {
    match source {
        exr::error::Error::Io(source) => io_error(path, source),
        source => ImageIoError::Exr {
            path: path.to_path_buf(),
            source,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A fresh, not yet existing path in a per-test scratch directory; removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(test: &str) -> Self {
            static COUNTER: AtomicUsize = AtomicUsize::new(0);
            let dir = std::env::temp_dir().join(format!(
                "furnace-film-io-{}-{}-{}",
                std::process::id(),
                test,
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            let _ = fs::remove_dir_all(&dir);
            Self(dir)
        }

        fn file(&self, name: &str) -> PathBuf {
            self.0.join(name)
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn the_same_image_gives_the_same_bytes_with_attributes_sorted_by_name() {
        let scratch = Scratch::new("bytes");
        let mut image = sample_image();
        for k in 0..24 {
            image
                .attributes
                .push((format!("furnace.k{k:02}"), format!("value {k}")));
        }
        let (a, b) = (scratch.file("a.exr"), scratch.file("b.exr"));
        write_exr(&a, &image).unwrap();
        write_exr(&b, &image).unwrap();
        let bytes = fs::read(&a).unwrap();
        assert_eq!(bytes, fs::read(&b).unwrap());
        // the header's names, in file order
        let mut names = Vec::new();
        let mut at = 8;
        loop {
            let end = at + bytes[at..].iter().position(|&c| c == 0).unwrap();
            if end == at {
                break;
            }
            names.push(bytes[at..end].to_vec());
            let type_end = end + 1 + bytes[end + 1..].iter().position(|&c| c == 0).unwrap();
            let size = i32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap());
            at = type_end + 5 + size as usize;
        }
        assert!(names.len() > 30, "{}", names.len());
        assert!(names.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(
            read_exr(&a).unwrap().attributes.len(),
            image.attributes.len()
        );
    }

    #[test]
    fn the_owned_writer_writes_the_borrowing_writers_file_and_errors() {
        let scratch = Scratch::new("owned");
        let (a, b) = (scratch.file("a.exr"), scratch.file("b.exr"));
        write_exr(&a, &sample_image()).unwrap();
        write_exr_owned(&b, sample_image()).unwrap();
        assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap());
        let mut short = sample_image();
        short.channels[0].1.pop();
        assert!(matches!(
            write_exr_owned(&scratch.file("short.exr"), short),
            Err(ImageIoError::ChannelLength { .. })
        ));
    }

    fn sample_image() -> Layers {
        let names = ["R", "G", "B", "X", "Y", "Z", "variance.Y"];
        let channels = names
            .iter()
            .enumerate()
            .map(|(c, name)| {
                #[allow(clippy::cast_precision_loss)]
                let values = (0..6).map(|i| (c * 10 + i) as f32 * 0.137 - 1.5).collect();
                ((*name).to_owned(), values)
            })
            .collect();
        Layers {
            width: 3,
            height: 2,
            channels,
            attributes: vec![
                (
                    "furnace.scene".to_owned(),
                    "cornell box, 1024 spp".to_owned(),
                ),
                ("owner".to_owned(), "furnace test suite ✓".to_owned()),
            ],
        }
    }

    #[test]
    fn exr_round_trip_is_bit_exact_with_exact_names() {
        let scratch = Scratch::new("roundtrip");
        let path = scratch.file("nested/dir/image.exr"); // parent dirs do not exist yet
        let mut image = sample_image();
        // Awkward values that must survive bit-exactly.
        image.channels[0].1[0] = f32::NAN;
        image.channels[0].1[1] = f32::INFINITY;
        image.channels[0].1[2] = -0.0;
        image.channels[0].1[3] = f32::MIN_POSITIVE / 2.0; // subnormal
        image.channels[0].1[4] = f32::MAX;

        write_exr(&path, &image).unwrap();
        let read = read_exr(&path).unwrap();

        assert_eq!((read.width, read.height), (3, 2));
        assert_eq!(read.channels.len(), image.channels.len());
        for (name, values) in &image.channels {
            let got = read
                .channel(name)
                .unwrap_or_else(|| panic!("channel {name} missing"));
            let want_bits: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
            let got_bits: Vec<u32> = got.iter().map(|v| v.to_bits()).collect();
            assert_eq!(got_bits, want_bits, "channel {name}");
        }
        let mut read_names: Vec<&str> = read.channels.iter().map(|(n, _)| n.as_str()).collect();
        read_names.sort_unstable();
        let mut want_names: Vec<&str> = image.channels.iter().map(|(n, _)| n.as_str()).collect();
        want_names.sort_unstable();
        assert_eq!(read_names, want_names);
        assert!(read_names.contains(&"variance.Y"));

        let mut want_attributes = image.attributes.clone();
        want_attributes.sort();
        assert_eq!(read.attributes, want_attributes);
    }

    #[test]
    fn exr_write_rejects_wrong_channel_length() {
        let scratch = Scratch::new("length");
        let path = scratch.file("bad.exr");
        let mut image = sample_image();
        image.channels[6].1.pop();
        match write_exr(&path, &image) {
            Err(ImageIoError::ChannelLength {
                channel,
                expected,
                found,
                ..
            }) => {
                assert_eq!((channel.as_str(), expected, found), ("variance.Y", 6, 5));
            }
            other => panic!("expected ChannelLength, got {other:?}"),
        }
        assert!(!path.exists());
    }

    #[test]
    fn exr_write_rejects_duplicate_channel_name() {
        let scratch = Scratch::new("duplicate");
        let mut image = sample_image();
        image.channels[4].0 = "R".to_owned();
        match write_exr(&scratch.file("dup.exr"), &image) {
            Err(ImageIoError::DuplicateChannel { channel, .. }) => assert_eq!(channel, "R"),
            other => panic!("expected DuplicateChannel, got {other:?}"),
        }
    }

    #[test]
    fn exr_write_rejects_zero_size() {
        let scratch = Scratch::new("zero");
        for (width, height) in [(0, 2), (3, 0), (0, 0)] {
            let image = Layers {
                width,
                height,
                channels: vec![("R".to_owned(), Vec::new())],
                attributes: Vec::new(),
            };
            let result = write_exr(&scratch.file("zero.exr"), &image);
            assert!(
                matches!(result, Err(ImageIoError::InvalidSize { .. })),
                "{width}x{height}: {result:?}"
            );
        }
    }

    #[test]
    fn exr_write_rejects_bad_names_and_attributes() {
        let scratch = Scratch::new("names");
        let path = scratch.file("names.exr");

        let mut image = sample_image();
        image.channels[0].0 = String::new();
        assert!(matches!(
            write_exr(&path, &image),
            Err(ImageIoError::InvalidChannelName { .. })
        ));

        let mut image = sample_image();
        image.channels.clear();
        assert!(matches!(
            write_exr(&path, &image),
            Err(ImageIoError::NoChannels { .. })
        ));

        for bad in ["channels", "name", "expTime", ""] {
            let mut image = sample_image();
            image.attributes.push((bad.to_owned(), "x".to_owned()));
            let result = write_exr(&path, &image);
            assert!(
                matches!(result, Err(ImageIoError::InvalidAttribute { .. })),
                "{bad:?}: {result:?}"
            );
        }

        let mut image = sample_image();
        image
            .attributes
            .push(("furnace.scene".to_owned(), "again".to_owned()));
        assert!(matches!(
            write_exr(&path, &image),
            Err(ImageIoError::InvalidAttribute { .. })
        ));
        assert!(!path.exists());
    }

    #[test]
    fn exr_read_missing_file_is_io_not_found() {
        let scratch = Scratch::new("missing");
        match read_exr(&scratch.file("does-not-exist.exr")) {
            Err(ImageIoError::Io { source, path }) => {
                assert_eq!(source.kind(), std::io::ErrorKind::NotFound);
                assert!(path.ends_with("does-not-exist.exr"));
            }
            other => panic!("expected Io(NotFound), got {other:?}"),
        }
    }

    #[test]
    fn exr_read_rejects_non_exr_file() {
        let scratch = Scratch::new("notexr");
        let path = scratch.file("not-an.exr");
        fs::create_dir_all(&scratch.0).unwrap();
        fs::write(&path, b"P3\n1 1\n255\n0 0 0\nthis is not an OpenEXR file").unwrap();
        let result = read_exr(&path);
        assert!(
            matches!(result, Err(ImageIoError::Exr { .. })),
            "{result:?}"
        );
        let message = result.unwrap_err().to_string();
        assert!(message.contains("not-an.exr"), "{message}");

        // A valid EXR cut short must also fail cleanly.
        let full = scratch.file("full.exr");
        write_exr(&full, &sample_image()).unwrap();
        let bytes = fs::read(&full).unwrap();
        for cut in [8, bytes.len() / 2, bytes.len() - 3] {
            fs::write(&path, &bytes[..cut]).unwrap();
            assert!(read_exr(&path).is_err(), "truncated at {cut}");
        }
    }

    #[test]
    fn exr_on_disk_format_is_rle_float_with_verbatim_names() {
        let scratch = Scratch::new("ondisk");
        let path = scratch.file("image.exr");
        write_exr(&path, &sample_image()).unwrap();
        let bytes = fs::read(&path).unwrap();
        let contains = |needle: &[u8]| bytes.windows(needle.len()).any(|w| w == needle);
        // Channel list entry: NUL-terminated full name, then pixel type 2 (FLOAT).
        assert!(contains(b"variance.Y\0\x02\0\0\0"));
        // compression attribute: name, type name, size 1, value 1 (RLE_COMPRESSION).
        assert!(contains(b"compression\0compression\0\x01\0\0\0\x01"));
        // Single part: no part name attribute.
        assert!(!contains(b"name\0string\0"));
    }

    #[test]
    fn exr_read_converts_half_and_u32_and_takes_first_layer() {
        use exr::prelude::f16;
        let scratch = Scratch::new("types");
        let path = scratch.file("types.exr");
        fs::create_dir_all(&scratch.0).unwrap();
        let half = [0.5_f32, -2.0, 65504.0, 1.0e-3];
        let uint = [0_u32, 1, 16_777_217, u32::MAX];
        let first = Layer::new(
            (2, 2),
            LayerAttributes::named("first"),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![
                AnyChannel::new(
                    "h",
                    FlatSamples::F16(half.iter().map(|&v| f16::from_f32(v)).collect()),
                ),
                AnyChannel::new("diffuse.id", FlatSamples::U32(uint.to_vec())),
            ])),
        );
        let second = Layer::new(
            (2, 2),
            LayerAttributes::named("second"),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
                "other",
                FlatSamples::F32(vec![9.0; 4]),
            )])),
        );
        let bounds = exr::meta::attribute::IntegerBounds::from_dimensions((2, 2));
        Image::from_layers(
            exr::meta::header::ImageAttributes::new(bounds),
            vec![first, second],
        )
        .write()
        .to_file(&path)
        .unwrap();

        let read = read_exr(&path).unwrap();
        let names: Vec<&str> = read.channels.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["diffuse.id", "h"]);
        let want_half: Vec<f32> = half.iter().map(|&v| f16::from_f32(v).to_f32()).collect();
        assert_eq!(read.channel("h").unwrap(), want_half.as_slice());
        #[allow(clippy::cast_precision_loss)]
        let want_uint: Vec<f32> = uint.iter().map(|&v| v as f32).collect();
        assert_eq!(read.channel("diffuse.id").unwrap(), want_uint.as_slice());
        // The part name is structural and not reported as an attribute.
        assert!(read.attributes.is_empty(), "{:?}", read.attributes);
    }

    fn decode_png(path: &Path) -> (u32, u32, Vec<u8>) {
        let file = std::io::BufReader::new(fs::File::open(path).unwrap());
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buffer).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buffer.truncate(info.buffer_size());
        (info.width, info.height, buffer)
    }

    #[test]
    fn png_srgb_exact_bytes() {
        let scratch = Scratch::new("png");
        let path = scratch.file("preview/out.png");
        let pixels = [
            [0.5, 1.0, 0.0],
            [f64::NAN, 0.2, 0.3],
            [2.0, -1.0, 0.5], // > 1 clamps to 255, < 0 to 0
            [0.001, 0.0, 1.0],
        ];
        write_png_srgb(&path, 2, 2, &pixels, 1.0).unwrap();
        let (width, height, bytes) = decode_png(&path);
        assert_eq!((width, height), (2, 2));
        #[rustfmt::skip]
        let expected = [
            188, 255, 0,    255, 0, 255,
            255, 0, 188,    3, 0, 255,
        ];
        assert_eq!(bytes, expected);

        // Exposure is applied before clamping and encoding.
        write_png_srgb(&path, 1, 1, &[[0.25, 0.5, 0.0]], 2.0).unwrap();
        assert_eq!(decode_png(&path).2, [188, 255, 0]);
    }

    #[test]
    fn png_rejects_bad_input() {
        let scratch = Scratch::new("pngbad");
        let path = scratch.file("bad.png");
        match write_png_srgb(&path, 2, 2, &[[0.0; 3]; 3], 1.0) {
            Err(ImageIoError::PixelCount {
                expected, found, ..
            }) => {
                assert_eq!((expected, found), (4, 3));
            }
            other => panic!("expected PixelCount, got {other:?}"),
        }
        assert!(matches!(
            write_png_srgb(&path, 0, 1, &[], 1.0),
            Err(ImageIoError::InvalidSize { .. })
        ));
        for exposure in [f64::NAN, f64::INFINITY, -1.0] {
            assert!(matches!(
                write_png_srgb(&path, 1, 1, &[[0.5; 3]], exposure),
                Err(ImageIoError::InvalidExposure { .. })
            ));
        }
        assert!(!path.exists());
    }
}
