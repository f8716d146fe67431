//! Resource limits for untrusted input: the memory budget that every allocation sized by a file or a flag is
//! checked against before it is made, file reads with a size cap, a cap on worker threads, and a guard that runs
//! a dependency which may panic without letting its panic message or backtrace reach the user.
//!
//! The budget is a value ([`Limits`]) handed to loaders ([`crate::scene::LoadOptions::limits`]) and renders
//! ([`crate::RenderSettings::limits`]); the command line sets it with `--memory-limit`. Its default is half of
//! the machine's physical memory. The same budget bounds the work a file can cause at load time (posing skins,
//! morph targets): one step per byte (`WorkBudget`). What a USD stage may compose has limits of its own
//! ([`Limits::usd_prims`], [`Limits::usd_layer_stack`]: `--max-prims`, `--max-sublayers`).

use std::cell::Cell;
use std::fmt;
use std::io::Read;
use std::path::Path;
use std::sync::Once;

/// Budget used when the physical memory cannot be read (not Linux): 8 GiB.
const FALLBACK_MEMORY_BYTES: u64 = 8 << 30;

/// Largest read from a file whose size is not known in advance (a device, a pipe). `/dev/zero` given as a
/// scene, buffer or VDB file ends in a clear error after this many bytes (256 MiB).
pub(crate) const MAX_STREAM_BYTES: u64 = 256 << 20;

/// Worker threads allowed per core: a larger `--threads` (or [`crate::RenderSettings::threads`]) is capped.
pub const THREADS_PER_CORE: usize = 8;

/// Prims a USD stage may compose by default ([`Limits::usd_prims`], `--max-prims`): about 40 s and 3.5 GB of
/// reading on the 2-core development machine (100,000 prims took 4.2 s and 340 MB).
pub(crate) const DEFAULT_USD_PRIMS: u64 = 1_000_000;

/// Entries one USD layer stack may expand to by default ([`Limits::usd_layer_stack`], `--max-sublayers`): far
/// more than the sublayers of real shots, while every prim `openusd` composes reads through each entry (a stack
/// of 8,191 entries over 112 prims took 1.6 s to load here, one of 32,767 entries 13 s).
pub(crate) const DEFAULT_USD_LAYER_STACK: u64 = 1000;

/// What one load or render may allocate, and how much a USD stage may compose.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Bytes that one allocation sized by a file or a flag may take: a film, a majorant structure, a decoded
    /// texture, a file read whole.
    pub memory_bytes: u64,
    /// Prims a USD stage may compose. Counted before composing, from the layers (each prim once per arc that
    /// brings it in), and again as the stage is read.
    pub usd_prims: u64,
    /// Entries one USD layer stack (a root layer and its sublayers, nested ones included) may expand to, a layer
    /// named twice counting twice, as `openusd` builds the stack. Counted before the stage is opened.
    pub usd_layer_stack: u64,
}

impl Default for Limits {
    /// Half of the physical memory (8 GiB where it cannot be read), `DEFAULT_USD_PRIMS` and
    /// `DEFAULT_USD_LAYER_STACK`.
    fn default() -> Self {
        Self::with_memory(physical_memory_bytes().map_or(FALLBACK_MEMORY_BYTES, |m| m / 2))
    }
}

impl Limits {
    /// A budget of `memory_bytes`, with the default composition limits.
    pub fn with_memory(memory_bytes: u64) -> Self {
        Self {
            memory_bytes,
            usd_prims: DEFAULT_USD_PRIMS,
            usd_layer_stack: DEFAULT_USD_LAYER_STACK,
        }
    }

    /// `Ok` if `bytes` fit the budget; else an error naming `what` would need them.
    pub fn check(&self, what: impl fmt::Display, bytes: u64) -> Result<(), OverBudget> {
        if bytes <= self.memory_bytes {
            Ok(())
        } else {
            Err(OverBudget {
                what: what.to_string(),
                bytes,
                budget: self.memory_bytes,
            })
        }
    }

    /// `Ok` if `count` items of `item_bytes` each fit the budget (an overflowing product does not).
    pub fn check_items(
        &self,
        what: impl fmt::Display,
        count: u64,
        item_bytes: u64,
    ) -> Result<(), OverBudget> {
        self.check(what, count.saturating_mul(item_bytes))
    }

    /// Steps of load-time work one load may take (a joint matrix, a morph-target vertex): one per byte of the
    /// memory budget, so `--memory-limit` raises both.
    pub fn work_steps(&self) -> u64 {
        self.memory_bytes
    }
}

/// The load-time work a file causes, counted as it is done and refused past [`Limits::work_steps`]: work that
/// grows with products of counts in a file (joints × poses, morph targets × vertices × instances) rather than
/// with the memory it fills.
#[derive(Debug)]
pub(crate) struct WorkBudget {
    /// Steps counted so far.
    used: Cell<u64>,
    /// The most steps allowed.
    limit: u64,
}

impl WorkBudget {
    /// A budget of [`Limits::work_steps`], none of it used.
    pub fn new(limits: &Limits) -> Self {
        Self {
            used: Cell::new(0),
            limit: limits.work_steps(),
        }
    }

    /// Counts `steps` more, before they are taken; an error naming `what` when the total would pass the budget.
    pub fn spend(&self, what: impl fmt::Display, steps: u64) -> Result<(), OverWork> {
        let total = self.used.get().saturating_add(steps);
        if total > self.limit {
            return Err(OverWork {
                what: what.to_string(),
                steps: total,
                budget: self.limit,
            });
        }
        self.used.set(total);
        Ok(())
    }
}

/// Load-time work refused because it would pass the work budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct OverWork {
    /// The work that would have been done.
    pub what: String,
    /// The load's steps with it.
    pub steps: u64,
    /// The budget in steps.
    pub budget: u64,
}

impl fmt::Display for OverWork {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} would bring the load's work to {} steps, over the work budget of {} steps (one per byte of the memory budget; raise it with --memory-limit)",
            self.what, self.steps, self.budget
        )
    }
}

impl std::error::Error for OverWork {}

/// An allocation refused because it exceeds the memory budget.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OverBudget {
    /// What would have been allocated.
    pub what: String,
    /// Bytes it needs (`u64::MAX` when the size overflows).
    pub bytes: u64,
    /// The budget in bytes.
    pub budget: u64,
}

impl fmt::Display for OverBudget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let needs = if self.bytes == u64::MAX {
            "more bytes than a 64-bit size holds".to_string()
        } else {
            format_bytes(self.bytes)
        };
        write!(
            f,
            "{} would take {needs}, over the memory budget of {} (raise it with --memory-limit)",
            self.what,
            format_bytes(self.budget)
        )
    }
}

impl std::error::Error for OverBudget {}

/// `bytes` in the largest binary unit that keeps a number ≥ 1 ("512 B", "1.5 GiB").
pub(crate) fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["KiB", "MiB", "GiB", "TiB", "PiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut value = bytes as f64 / 1024.0;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.1} {}", UNITS[unit])
}

/// Why a `--memory-limit` value is not a size.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SizeError {
    /// Not a number with an optional K, M, G or T suffix.
    #[error("'{0}' is not a size (examples: 4096, 512M, 4G)")]
    NotASize(String),
    /// Below one byte, or too large for 64 bits.
    #[error("'{0}' is not a size of at least one byte")]
    BelowOneByte(String),
}

/// Parses a size with an optional binary suffix: `4096`, `512M`, `4G`, `1.5T` (K, M, G, T; an optional `iB` or
/// `B` after it).
pub fn parse_size(text: &str) -> Result<u64, SizeError> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let number = upper
        .trim_end_matches("IB")
        .trim_end_matches('B')
        .trim_end();
    let (digits, shift) = match number.chars().last() {
        Some('K') => (&number[..number.len() - 1], 10),
        Some('M') => (&number[..number.len() - 1], 20),
        Some('G') => (&number[..number.len() - 1], 30),
        Some('T') => (&number[..number.len() - 1], 40),
        _ => (number, 0),
    };
    let value: f64 = digits
        .trim()
        .parse()
        .map_err(|_| SizeError::NotASize(t.to_owned()))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(SizeError::BelowOneByte(t.to_owned()));
    }
    Ok(bytes as u64)
}

/// The machine's physical memory, from `/proc/meminfo` (Linux).
pub(crate) fn physical_memory_bytes() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The most worker threads a render uses: [`THREADS_PER_CORE`] per core.
pub fn max_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get()) * THREADS_PER_CORE
}

/// A file opened by [`open_file`]: a regular file, to be read as the caller needs, or the whole contents of a
/// device, read already (its size is unknown until read).
pub(crate) enum OpenedFile {
    /// A regular file of this many bytes, within the memory budget.
    Regular(std::fs::File, u64),
    /// Everything a device gave, at most [`MAX_STREAM_BYTES`] or the budget.
    Read(Vec<u8>),
}

/// Opens a file for reading, refusing a folder, a pipe or socket, and a regular file larger than the memory
/// budget before reading any of it; a device (whose size is unknown) is read at once, stopping after
/// [`MAX_STREAM_BYTES`] or the budget, whichever is smaller.
pub(crate) fn open_file(path: &Path, limits: &Limits) -> std::io::Result<OpenedFile> {
    use std::io::{Error, ErrorKind};
    refuse_pipes_and_sockets(path)?;
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_dir() {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "is a folder, not a file",
        ));
    }
    if meta.is_file() {
        if meta.len() > limits.memory_bytes {
            return Err(Error::new(
                ErrorKind::InvalidData,
                format!(
                    "the file is {}, over the memory budget of {} (raise it with --memory-limit)",
                    format_bytes(meta.len()),
                    format_bytes(limits.memory_bytes)
                ),
            ));
        }
        return Ok(OpenedFile::Regular(file, meta.len()));
    }
    let cap = MAX_STREAM_BYTES.min(limits.memory_bytes);
    let mut bytes = Vec::new();
    file.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(Error::new(
            ErrorKind::InvalidData,
            format!(
                "not a regular file, and it gives more than {} (an endless device?)",
                format_bytes(cap)
            ),
        ));
    }
    Ok(OpenedFile::Read(bytes))
}

/// Reads a whole file, refusing one larger than the memory budget before reading it, and stopping a device or
/// pipe (whose size is unknown) after `MAX_STREAM_BYTES` or the budget, whichever is smaller.
pub fn read_file(path: &Path, limits: &Limits) -> std::io::Result<Vec<u8>> {
    match open_file(path, limits)? {
        OpenedFile::Regular(file, len) => {
            let mut bytes = Vec::with_capacity(len as usize);
            file.take(limits.memory_bytes).read_to_end(&mut bytes)?;
            Ok(bytes)
        }
        OpenedFile::Read(bytes) => Ok(bytes),
    }
}

/// Refuses a named pipe (FIFO) or a socket before it is opened: opening a pipe with no writer blocks forever,
/// and a scene, texture or grid never arrives through one. Devices (`/dev/zero`) are left to the caller's cap.
pub(crate) fn refuse_pipes_and_sockets(path: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        // A path that cannot be examined is left to the open that follows, which reports why.
        let Ok(meta) = std::fs::metadata(path) else {
            return Ok(());
        };
        let kind = meta.file_type();
        let what = if kind.is_fifo() {
            "a named pipe (FIFO)"
        } else if kind.is_socket() {
            "a socket"
        } else {
            return Ok(());
        };
        Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("is {what}, not a file"),
        ))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        Ok(())
    }
}

/// Why an image could not be decoded ([`decode_image`]); its `Display` is the one-line message.
#[derive(Debug)]
pub(crate) enum ImageError {
    /// The decoder refused the bytes: its own message, on one line.
    Decoder(String),
    /// The image's header gives more texels than the memory budget holds.
    OverBudget(OverBudget),
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImageError::Decoder(message) => f.write_str(message),
            ImageError::OverBudget(over) => over.fmt(f),
        }
    }
}

/// The message of a panic that [`catch_quietly`] caught inside a dependency.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct PanicMessage(pub(crate) String);

impl fmt::Display for PanicMessage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Decodes a PNG, JPEG or other image the `image` crate reads, from bytes, refusing before decoding one whose
/// header gives more than the budget allows at `bytes_per_texel` (what the caller keeps per texel, beyond the
/// decoder's own buffers, which the decoder's `max_alloc` bounds). Errors are one line.
pub(crate) fn decode_image(
    bytes: &[u8],
    limits: &Limits,
    bytes_per_texel: u64,
) -> Result<image::DynamicImage, ImageError> {
    decode_image_named(bytes, None, limits, bytes_per_texel)
}

/// [`decode_image`] of the file `name`: a format that has no signature to recognise it by (TGA, which USD assets
/// use for scalar maps) is taken from the name's extension.
pub(crate) fn decode_image_named(
    bytes: &[u8],
    name: Option<&Path>,
    limits: &Limits,
    bytes_per_texel: u64,
) -> Result<image::DynamicImage, ImageError> {
    let by_extension = name
        .and_then(|n| n.extension())
        .and_then(image::ImageFormat::from_extension)
        .filter(|f| *f == image::ImageFormat::Tga);
    let decoder_error = |e: &dyn fmt::Display| ImageError::Decoder(one_line(&e.to_string(), 200));
    let reader = || -> Result<image::ImageReader<std::io::Cursor<&[u8]>>, ImageError> {
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ImageError::Decoder(e.to_string()))?;
        if reader.format().is_none() {
            if let Some(format) = by_extension {
                reader.set_format(format);
            }
        }
        let mut decoder_limits = image::Limits::default();
        decoder_limits.max_alloc = Some(limits.memory_bytes);
        reader.limits(decoder_limits);
        Ok(reader)
    };
    let (width, height) = reader()?.into_dimensions().map_err(|e| decoder_error(&e))?;
    limits
        .check_items(
            format_args!("the {width}x{height} image"),
            width as u64 * height as u64,
            bytes_per_texel,
        )
        .map_err(ImageError::OverBudget)?;
    reader()?.decode().map_err(|e| decoder_error(&e))
}

thread_local! {
    /// Set while [`catch_quietly`] runs on this thread: the panic hook then prints nothing.
    static QUIET: Cell<bool> = const { Cell::new(false) };
}

/// Runs `f`, which may panic inside a dependency, and returns its panic message as `Err` instead of unwinding.
/// While `f` runs, a panic on this thread prints nothing (no message, no backtrace); panics elsewhere print as
/// before. The first call wraps the process's panic hook with one that checks a per-thread flag.
pub(crate) fn catch_quietly<T>(f: impl FnOnce() -> T) -> Result<T, PanicMessage> {
    static WRAP_HOOK: Once = Once::new();
    WRAP_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Cell::get) {
                previous(info);
            }
        }));
    });
    let was_quiet = QUIET.with(|q| q.replace(true));
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was_quiet));
    outcome.map_err(|payload| {
        PanicMessage(
            payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                .unwrap_or_else(|| "a panic without a message".to_owned()),
        )
    })
}

/// The longest error or warning line that the CLI prints and the Python module raises: messages quoting file
/// contents are cut there ([`one_line`]).
pub const MAX_MESSAGE_CHARS: usize = 1000;

/// `text` as one line of printable ASCII at most `max_chars` long: line breaks become `" / "`, other control
/// characters and non-ASCII characters become `\xNN` or `\u{...}` escapes, and a longer text is cut with `…`
/// spelled as `...`. Error messages that quote file contents pass through this.
pub fn one_line(text: &str, max_chars: usize) -> String {
    let mut out = String::with_capacity(text.len().min(max_chars + 8));
    let mut chars = text.trim_end().chars().peekable();
    while let Some(c) = chars.next() {
        if out.len() >= max_chars {
            out.push_str("...");
            break;
        }
        match c {
            '\r' if chars.peek() == Some(&'\n') => {}
            '\n' | '\r' => out.push_str(" / "),
            '\t' => out.push(' '),
            c if c.is_ascii_graphic() || c == ' ' => out.push(c),
            c if (c as u32) < 0x100 => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_size("4096"), Ok(4096));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("4GiB"), Ok(4 << 30));
        assert_eq!(parse_size("1.5k"), Ok(1536));
        assert!(parse_size("0").is_err());
        assert!(parse_size("-3G").is_err());
        assert!(parse_size("lots").is_err());
        assert!(parse_size("1e300T").is_err());
    }

    #[test]
    fn the_budget_refuses_overflowing_and_large_sizes() {
        let limits = Limits::with_memory(1000);
        assert!(limits.check("a film", 1000).is_ok());
        let err = limits.check_items("a film", u64::MAX / 2, 16).unwrap_err();
        assert_eq!(err.bytes, u64::MAX);
        assert!(err.to_string().starts_with("a film would take more bytes"));
        assert!(limits.check("x", 1001).is_err());
    }

    #[test]
    fn the_work_budget_counts_every_step_and_refuses_past_it() {
        let work = WorkBudget::new(&Limits::with_memory(100));
        assert!(work.spend("posing", 60).is_ok());
        let err = work.spend("more posing", 41).unwrap_err();
        assert_eq!((err.steps, err.budget), (101, 100));
        assert!(err.to_string().contains("--memory-limit"), "{err}");
        assert!(
            work.spend("the rest", 40).is_ok(),
            "a refused step is not counted"
        );
        assert!(work.spend("one more", 1).is_err());
    }

    #[test]
    fn one_line_escapes_and_cuts() {
        let s = one_line("bad\0name\nline two \u{e9}", 100);
        assert_eq!(s, "bad\\x00name / line two \\xe9");
        let long = one_line(&"x".repeat(500), 64);
        assert_eq!(long.len(), 67);
        assert!(long.ends_with("..."));
    }

    #[test]
    fn endless_devices_end_in_an_error() {
        let path = Path::new("/dev/zero");
        if !path.exists() {
            return;
        }
        let err = read_file(path, &Limits::with_memory(1 << 20)).unwrap_err();
        assert!(err.to_string().contains("endless device"), "{err}");
    }

    #[test]
    fn images_larger_than_the_budget_are_refused_before_decoding() {
        let mut png = Vec::new();
        image::RgbaImage::new(64, 64)
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        // 64 × 64 texels at 26 bytes are 104 KiB: within 1 MiB, not within 64 KiB.
        assert!(decode_image(&png, &Limits::with_memory(1 << 20), 26).is_ok());
        let err = decode_image(&png, &Limits::with_memory(64 << 10), 26).unwrap_err();
        assert!(
            err.to_string().contains("64x64 image") && err.to_string().contains("memory budget"),
            "{err}"
        );
        assert!(decode_image(b"not an image", &Limits::default(), 26).is_err());
    }

    #[test]
    fn quiet_panics_become_errors() {
        let r: Result<(), PanicMessage> = catch_quietly(|| panic!("inside a dependency"));
        assert_eq!(r, Err(PanicMessage("inside a dependency".to_owned())));
        assert_eq!(catch_quietly(|| 7), Ok(7));
    }
}
