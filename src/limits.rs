//! Limits on what furnace accepts, enforced before anything is allocated for it, each with a
//! named error: image size, the work of a render, file sizes, meshes and checks.

/// Largest image side, pixels.
pub const MAX_IMAGE_SIDE: u64 = 1 << 16;

/// Largest image, pixels (a 4096² image): the film keeps 200 bytes per pixel (the count, and
/// the mean and second to fourth central sums in f64 for six channels), 3.4 GB at this size.
pub const MAX_PIXELS: u64 = 1 << 24;

/// Memory the light tracer's film state may take, bytes: while the pending nodes of the merge
/// tree (up to 7 images of 200 bytes per pixel) and the chunks in flight (392 bytes per pixel
/// each) are held. Fewer chunks run at once when many threads would pass it; an image whose
/// state passes it with one chunk in flight (over about 7.2 M pixels) is refused.
pub const MAX_LIGHT_TRACER_BYTES: u64 = 12 << 30;

/// Default work budget of `furnace render`, camera or light paths (width × height × spp): about
/// 5 hours at 1 M paths/s. `--max-samples` raises it.
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 34;

/// Largest text file read (scene, manifest, renderer table, CSV, regions), bytes: parsing a
/// TOML document takes tens of times its size in memory.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Largest mesh file read (OBJ, PLY), bytes.
pub const MAX_MESH_BYTES: u64 = 1 << 30;

/// Most triangles in one scene: about 1 KB each in the mesh, the BVH and the pairs.
pub const MAX_TRIANGLES: u64 = 1 << 24;

/// Most vertices in one mesh file: 24 bytes each (three f64), 805 MB at the limit, checked
/// before they are stored (a binary PLY of one-byte coordinates holds 3 bytes of file per
/// vertex). Twice [`MAX_TRIANGLES`]: a closed mesh has about half as many vertices as
/// triangles, so only unused or unshared vertices meet it.
pub const MAX_VERTICES: u64 = 1 << 25;

/// Most worker threads a command may be given (`--threads`): each thread holds a stack and its
/// own film chunk, and thousands of them only exhaust the machine's process limit.
pub const MAX_THREADS: usize = 1024;

/// Most checks a manifest may expand to (after `vary`).
pub const MAX_CHECKS: usize = 10_000;

/// Largest coordinate magnitude of any shape's bounds, scene units: f64 positions there still
/// resolve 2e-4 units, and the BVH's f32 boxes stay finite.
pub const MAX_COORDINATE: f64 = 1e12;

/// Smallest extent (largest side of the bounding box) of any shape, scene units: the
/// mirror image of [`MAX_COORDINATE`]; below it squared lengths leave f64's normal range.
pub const MIN_EXTENT: f64 = 1e-12;

/// Most channels of an EXR furnace reads (with [`MAX_PIXELS`], 4 GiB of f32 at most).
pub const MAX_CHANNELS: usize = 64;

/// Longest piece of user input quoted in a message, characters.
pub const MAX_QUOTED: usize = 120;

/// Longest model name a model server may declare, bytes (every check line names its model).
pub const MAX_MODEL_NAME: usize = 200;

/// A limit that input exceeded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} is {value}; the limit is {limit}{how}")]
pub struct LimitError {
    /// What was too large.
    pub what: String,
    /// Its size.
    pub value: u64,
    /// The limit.
    pub limit: u64,
    /// How to raise it, when it can be raised (starts with "; ").
    pub how: String,
}

/// Checks an image size against [`MAX_IMAGE_SIDE`] and [`MAX_PIXELS`].
pub fn image(width: u64, height: u64) -> Result<(), LimitError> {
    for (what, v) in [("the image width", width), ("the image height", height)] {
        if v > MAX_IMAGE_SIDE {
            return Err(LimitError {
                what: what.into(),
                value: v,
                limit: MAX_IMAGE_SIDE,
                how: String::new(),
            });
        }
    }
    let pixels = width.saturating_mul(height);
    if pixels > MAX_PIXELS {
        return Err(LimitError {
            what: format!("the pixel count of a {width}x{height} image"),
            value: pixels,
            limit: MAX_PIXELS,
            how: " (the film needs 200 bytes per pixel)".into(),
        });
    }
    Ok(())
}

/// Peak memory of a camera render (path tracer or radiosity), bytes per pixel: the film's 200
/// and the output images' channels. Measured: 294 MB at 1024² and 1122 MB at 2048², one
/// sample per pixel (docs/hostile-input.md).
pub const CAMERA_RENDER_PIXEL_BYTES: u64 = 270;

/// Bytes a film keeps per pixel: the count, and the mean and second to fourth central sums
/// in f64 for six channels.
pub const FILM_PIXEL_BYTES: u64 = 200;

/// Memory a process needs besides its images, bytes (the binary, the scene, the thread stacks).
pub const BASE_BYTES: u64 = 32 << 20;

/// Memory this process may take, bytes, where the system says: `hard`, what it cannot pass
/// (the least of what the address-space limit leaves, `/proc/self/limits` less
/// `/proc/self/status`'s VmSize; what the cgroup's `memory.max` leaves over `memory.current`;
/// and the machine's memory and swap), and `soft`, what is free now (`/proc/meminfo`'s
/// MemAvailable and SwapFree; some reclaimable caches are not counted there). None where
/// unknown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryRoom {
    /// Bytes no allocation can pass.
    pub hard: Option<u64>,
    /// Bytes free now.
    pub soft: Option<u64>,
}

/// This process's [`MemoryRoom`].
pub fn memory_room() -> MemoryRoom {
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let meminfo = read("/proc/meminfo");
    let kib = |key: &str| {
        meminfo
            .as_deref()
            .and_then(|m| field(m, key))
            .map(|k| k * 1024)
    };
    let machine = kib("MemTotal:").map(|t| t + kib("SwapTotal:").unwrap_or(0));
    let soft = kib("MemAvailable:").map(|a| a + kib("SwapFree:").unwrap_or(0));
    let address_space = read("/proc/self/limits")
        .and_then(|l| field(&l, "Max address space"))
        .and_then(|limit| {
            let status = read("/proc/self/status")?;
            Some(limit.saturating_sub(field(&status, "VmSize:")? * 1024))
        });
    // cgroup v2: "max" (no limit) does not parse
    let cgroup = read("/sys/fs/cgroup/memory.max")
        .and_then(|m| m.trim().parse::<u64>().ok())
        .map(|max| {
            let current = read("/sys/fs/cgroup/memory.current")
                .and_then(|c| c.trim().parse::<u64>().ok())
                .unwrap_or(0);
            max.saturating_sub(current)
        });
    let hard = [address_space, cgroup, machine].into_iter().flatten().min();
    MemoryRoom { hard, soft }
}

/// Checks that `need` bytes for `what` fit in this process's [`memory_room`]: past the hard
/// room it is refused by name (before anything is allocated, rather than aborted when an
/// allocation fails); past what is free now, the answer is a warning to print. Nothing is
/// checked where the system says nothing.
pub fn memory(what: &str, need: u64) -> Result<Option<String>, LimitError> {
    let room = memory_room();
    if let Some(hard) = room.hard.filter(|&h| need > h) {
        return Err(LimitError {
            what: format!("the memory (bytes) {what} needs"),
            value: need,
            limit: hard,
            how: " (what this process may take: its address-space limit, its cgroup's memory.max, or the machine's memory and swap); render fewer pixels".into(),
        });
    }
    Ok(room.soft.filter(|&s| need > s).map(|s| {
        format!(
            "{what} needs about {:.1} GiB, more than the {:.1} GiB free now (memory and swap): it may be slow or killed",
            need as f64 / (1u64 << 30) as f64,
            s as f64 / (1u64 << 30) as f64
        )
    }))
}

/// `s` cut to [`MAX_QUOTED`] characters (with "…" when cut), for quoting user input.
pub fn quote(s: &str) -> String {
    let mut it = s.chars();
    let head: String = it.by_ref().take(MAX_QUOTED).collect();
    if it.next().is_some() {
        format!("{head}… ({} bytes)", s.len())
    } else {
        head
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_beyond_what_the_process_may_take_is_refused_by_name() {
        // the system reports its memory here (Linux); a need past any machine's is refused
        if memory_room().hard.is_some() {
            let e = memory("a test", u64::MAX).unwrap_err().to_string();
            assert!(
                e.starts_with(
                    "the memory (bytes) a test needs is 18446744073709551615; the limit is "
                ),
                "{e}"
            );
            assert_eq!(memory("a test", 1), Ok(None));
        }
    }

    #[test]
    fn images_beyond_the_limits_are_refused_by_name() {
        assert!(image(4096, 4096).is_ok());
        let e = image(1_000_000_000, 1).unwrap_err();
        assert!(e
            .to_string()
            .contains("the image width is 1000000000; the limit is 65536"));
        let e = image(65536, 65536).unwrap_err();
        assert!(e
            .to_string()
            .contains("image is 4294967296; the limit is 16777216"));
    }

    #[test]
    fn long_input_is_quoted_short() {
        assert_eq!(quote("abc"), "abc");
        let q = quote(&"x".repeat(1000));
        assert!(
            q.starts_with(&"x".repeat(120)) && q.ends_with("(1000 bytes)"),
            "{q}"
        );
    }
}
