//! File formats, each in one home: meshes (OBJ and PLY in, PLY out), CSV tables, images
//! (OpenEXR in and out, PNG previews out), located errors with plain words for TOML's type and
//! key errors, and temporary paths removed on interrupt with the one TOML loader every text
//! input uses. Plain data in and out: nothing here knows scenes, films or checks.

pub mod cleanup;
pub mod csv;
pub mod image;
pub mod located;
pub mod mesh;
pub mod process;
pub mod suggest;

pub use located::{
    check_writable, parse_toml, read_capped, read_small_text, read_text, write_atomic, Destination,
    LocatedError, Source,
};
