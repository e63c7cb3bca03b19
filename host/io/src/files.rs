//! Writing files whole or not at all.
//!
//! Every output is written beside its target under a hidden temporary name, flushed with
//! every error checked, synced to disk and renamed into place. A reader never sees half a
//! file; a failure (full disk, a closed pipe, an encoder error) removes the temporary and
//! leaves the previous file, if any, as it was. Outputs of several files are a [`Batch`]:
//! every file is written and synced before the first is renamed into place, so a failure
//! leaves the old set whole.
//!
//! For tests, [`fail_writes_after`] makes the process's outputs fail once so many bytes
//! have been written in all, as a disk that fills up midway would
//! (`ErrorKind::StorageFull`); the `rollfuse` command sets it from the environment
//! variable [`FAIL_WRITES_AFTER`].

use crate::invalid;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The environment variable from which the `rollfuse` command sets [`fail_writes_after`]
/// (tests).
pub const FAIL_WRITES_AFTER: &str = "ROLLFUSE_FAIL_WRITES_AFTER";

/// Why an output was not written: the file system's fault ([`WriteError::Io`]: a full
/// disk, no permission, a device error) told apart from where the output was pointed
/// ([`WriteError::Refused`]) and from the content's own error ([`WriteError::Content`]).
/// In every case the previous file, if any, is as it was.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The operating system refused or failed a step.
    #[error("cannot {doing} {}", path.display())]
    Io {
        /// The step, in words ("write", "move into place", …).
        doing: &'static str,
        /// The file or folder it was done to.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The output was asked for in a way it cannot be written: pointed at something it
    /// must not replace (not a regular file, a loop of links, an input, another output of
    /// the same run, a path whose folder is a file) or named or shaped for a format this
    /// writer does not take.
    #[error("{0}")]
    Refused(String),
    /// The content could not be made: the error of the code that writes it.
    #[error(transparent)]
    Content(anyhow::Error),
}

impl crate::invalid::Invalid for WriteError {
    fn invalid(message: String) -> Self {
        Self::Refused(message)
    }
}

impl WriteError {
    /// `source` as the failure of `doing` to `path`.
    pub fn io<'a>(doing: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> Self + 'a {
        move |source| Self::Io {
            doing,
            path: path.to_path_buf(),
            source,
        }
    }

    /// The operating system's error kind where the file system failed (for the content's
    /// error, anywhere among its causes): `StorageFull` for a full disk (`Other`, with the
    /// system's message, where the PNG encoder passed it on).
    pub fn io_kind(&self) -> Option<std::io::ErrorKind> {
        io_cause(self).map(std::io::Error::kind)
    }
}

/// The first I/O error among `e` and its causes, looking into the content errors an
/// output keeps (a chain passes over their causes: they are transparent).
pub fn io_cause<'a>(e: &'a (dyn std::error::Error + 'static)) -> Option<&'a std::io::Error> {
    let mut next = Some(e);
    while let Some(cause) = next {
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            return Some(io);
        }
        if let Some(WriteError::Content(content)) = cause.downcast_ref::<WriteError>() {
            return content.chain().find_map(io_cause);
        }
        next = cause.source();
    }
    None
}

/// A temporary path beside `target`: same folder (so the rename stays on one file
/// system), hidden, unique to this process and this call (two outputs of one name in a
/// batch get two temporaries).
///
/// The first temporary a process makes in a folder sweeps it of the temporaries that
/// processes no longer running left there ([`sweep_stale`]).
pub fn temporary_beside(target: &Path, tag: &str) -> PathBuf {
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let parent = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    sweep_once(parent);
    parent.join(format!(".{name}.{tag}-{}-{call}", std::process::id()))
}

/// An output folder made for a command: the folders it made are removed again when it is
/// dropped while they are still empty, so a command that fails before writing anything
/// leaves nothing behind (a folder that holds anything stays).
#[derive(Debug)]
pub struct NewFolder {
    /// The folders made, the innermost first.
    made: Vec<PathBuf>,
}

impl NewFolder {
    /// Makes the folder of the file `path` and its missing parents.
    pub fn for_file(path: &Path) -> Result<Self, WriteError> {
        Self::create(folder_of(path))
    }

    /// Makes `path` and its missing parents.
    pub fn create(path: &Path) -> Result<Self, WriteError> {
        let made: Vec<PathBuf> = path
            .ancestors()
            .filter(|p| !p.as_os_str().is_empty() && !p.exists())
            .map(Path::to_path_buf)
            .collect();
        std::fs::create_dir_all(path).map_err(WriteError::io("create output folder", path))?;
        Ok(Self { made })
    }
}

impl Drop for NewFolder {
    fn drop(&mut self) {
        // `remove_dir` removes only an empty folder: anything written keeps it.
        for dir in &self.made {
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// The tags of [`temporary_beside`]'s names.
const TEMPORARY_TAGS: [&str; 3] = ["part", "new", "old"];

/// The process that made `file_name`, if it is one of [`temporary_beside`]'s names
/// (`.NAME.TAG-PID-CALL`, perhaps with `.png` after).
pub fn temporary_owner(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?;
    let rest = rest.strip_suffix(".png").unwrap_or(rest);
    let (front, call) = rest.rsplit_once('-')?;
    let (front, pid) = front.rsplit_once('-')?;
    let (_, tag) = front.rsplit_once('.')?;
    let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
    (TEMPORARY_TAGS.contains(&tag) && digits(call) && digits(pid)).then(|| pid.parse().ok())?
}

/// [`sweep_stale`] of `dir`, once per process.
fn sweep_once(dir: &Path) {
    static SWEPT: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let key = resolved(dir);
    let mut swept = SWEPT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if !swept.contains(&key) {
        swept.push(key);
        drop(swept);
        sweep_stale(dir);
    }
}

/// Removes from `dir` the temporaries ([`temporary_beside`]'s names) of processes of
/// this machine that are no longer running: what a killed run left. Where it cannot be
/// told whether a process runs (no `/proc`), nothing is removed. Returns how many went.
pub fn sweep_stale(dir: &Path) -> usize {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return 0;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mine = std::process::id();
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(owner) = name.to_str().and_then(temporary_owner) else {
            continue;
        };
        if owner == mine || proc.join(owner.to_string()).exists() {
            continue;
        }
        let path = entry.path();
        let gone = match entry.file_type() {
            Ok(t) if t.is_dir() => std::fs::remove_dir_all(&path),
            _ => std::fs::remove_file(&path),
        };
        removed += usize::from(gone.is_ok());
    }
    removed
}

/// The file an output to `target` is written to: `target` itself, or, when it is a
/// symbolic link, the file the link leads to (so the link stays a link, its target
/// replaced whole). Anything but a regular file there — a FIFO, a device, a socket, a
/// folder — is refused: an output never replaces what the user pointed at with something
/// else.
pub fn output_target(target: &Path) -> Result<PathBuf, WriteError> {
    let mut at = target.to_path_buf();
    // As many links as the kernel follows in one path.
    for _ in 0..40 {
        let meta = match std::fs::symlink_metadata(&at) {
            Ok(meta) => meta,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(at),
            Err(e) => return Err(WriteError::io("look at", &at)(e)),
        };
        let kind = meta.file_type();
        if kind.is_symlink() {
            let to = std::fs::read_link(&at).map_err(WriteError::io("read the link", &at))?;
            at = match at.parent() {
                Some(dir) if to.is_relative() => dir.join(to),
                _ => to,
            };
            continue;
        }
        if !kind.is_file() {
            invalid!(
                "{} is {}: outputs are written to regular files only",
                target.display(),
                special_kind(&kind)
            );
        }
        return Ok(at);
    }
    invalid!("{} is a loop of symbolic links", target.display())
}

/// What a file that is not a regular file is, in words.
fn special_kind(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO";
        }
        if kind.is_char_device() || kind.is_block_device() {
            return "a device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    if kind.is_dir() {
        "a folder"
    } else {
        "not a regular file"
    }
}

/// Where `path` really is: links and `..` resolved, through its folder when the file does
/// not exist yet.
pub fn resolved(path: &Path) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match (std::fs::canonicalize(parent), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

/// Refuses, before any work, an output that is one of the inputs: `inputs` are each
/// named by what they are (`"input frame"`, `"background"`, `"recording"`, …).
pub fn refuse_overwriting(outputs: &[&Path], inputs: &[(&str, &Path)]) -> Result<(), WriteError> {
    for out in outputs {
        let target = resolved(out);
        if let Some((what, input)) = inputs.iter().find(|(_, p)| resolved(p) == target) {
            invalid!(
                "{} is the {what} {}: refusing to overwrite an input",
                out.display(),
                input.display()
            );
        }
    }
    Ok(())
}

/// Refuses, before any work, two outputs that are one file (the second would replace the
/// first): `what` says how they came to share it.
pub fn refuse_duplicate_outputs(outputs: &[&Path], what: &str) -> Result<(), WriteError> {
    let mut seen = std::collections::HashSet::new();
    for out in outputs {
        if !seen.insert(resolved(out)) {
            invalid!(
                "{} would be written twice ({what}): refusing to lose one of them",
                out.display()
            );
        }
    }
    Ok(())
}

/// The bytes every output of this process may still take, once [`fail_writes_after`] set
/// them.
static ROOM: std::sync::OnceLock<std::sync::atomic::AtomicU64> = std::sync::OnceLock::new();

/// Makes this process's outputs fail once `bytes` have been written in all, as a disk
/// that fills up midway would (a test seam), counting from the call. Set once: returns
/// `false`, changing nothing, if it was set already.
pub fn fail_writes_after(bytes: u64) -> bool {
    ROOM.set(std::sync::atomic::AtomicU64::new(bytes)).is_ok()
}

/// Refuses, before any work, inputs inside `folder`, an output folder replaced whole
/// ([`replace_folder`]).
pub fn refuse_inside(folder: &Path, inputs: &[(&str, &Path)]) -> Result<(), WriteError> {
    let folder_at = resolved(folder);
    if let Some((what, input)) = inputs
        .iter()
        .find(|(_, p)| resolved(p).starts_with(&folder_at))
    {
        invalid!(
            "the {what} {} is inside {}, which is replaced whole: refusing to remove an input",
            input.display(),
            folder.display()
        );
    }
    Ok(())
}

/// An output file being written (its temporary).
pub struct Output {
    file: File,
}

impl Output {
    fn create(tmp: &Path) -> Result<Self, WriteError> {
        let file = File::create(tmp).map_err(WriteError::io("create", tmp))?;
        Ok(Self { file })
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        use std::sync::atomic::Ordering::Relaxed;
        let mut n = buf.len();
        if let Some(room) = ROOM.get() {
            let left = room.load(Relaxed);
            if left == 0 && n > 0 {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "no space left on device",
                ));
            }
            n = n.min(usize::try_from(left).unwrap_or(usize::MAX));
        }
        let n = self.file.write(&buf[..n])?;
        if let Some(room) = ROOM.get() {
            room.fetch_sub(n as u64, Relaxed);
        }
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Flushes and syncs a finished temporary.
fn finish(writer: BufWriter<Output>, target: &Path) -> Result<(), WriteError> {
    let out = writer
        .into_inner()
        .map_err(|e| WriteError::io("write", target)(e.into_error()))?;
    out.file
        .sync_all()
        .map_err(WriteError::io("sync to disk", target))
}

/// Files written whole, then moved into place together by [`Batch::commit`]. Dropped
/// uncommitted (an error on the way), its temporaries are removed and every target is
/// left as it was.
#[derive(Default)]
pub struct Batch {
    /// (temporary, target), written and synced.
    ready: Vec<(PathBuf, PathBuf)>,
}

impl Batch {
    /// An empty batch.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `target`'s content into a synced temporary beside it; `fill` writes it.
    pub fn add(
        &mut self,
        target: &Path,
        fill: impl FnOnce(&mut BufWriter<Output>) -> anyhow::Result<()>,
    ) -> Result<(), WriteError> {
        let target = &output_target(target)?;
        let tmp = temporary_beside(target, "part");
        let result = (|| {
            let mut writer = BufWriter::with_capacity(1 << 16, Output::create(&tmp)?);
            fill(&mut writer).map_err(WriteError::Content)?;
            finish(writer, target)
        })();
        match result {
            Ok(()) => {
                self.ready.push((tmp, target.clone()));
                Ok(())
            }
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    /// [`Batch::add`] of a byte string.
    pub fn add_bytes(&mut self, target: &Path, bytes: &[u8]) -> Result<(), WriteError> {
        self.add(target, |w| {
            w.write_all(bytes)
                .map_err(|e| WriteError::io("write", target)(e).into())
        })
    }

    /// Moves every file into place, in the order they were added (so an index added last
    /// appears last).
    pub fn commit(mut self) -> Result<(), WriteError> {
        for (tmp, target) in std::mem::take(&mut self.ready) {
            if let Err(e) = std::fs::rename(&tmp, &target) {
                let _ = std::fs::remove_file(&tmp);
                return Err(WriteError::io("move into place", &target)(e));
            }
        }
        Ok(())
    }
}

impl Drop for Batch {
    fn drop(&mut self) {
        for (tmp, _) in &self.ready {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Writes `target` whole or not at all: `fill` writes the content into a buffered
/// temporary beside it, which is flushed, synced and renamed over `target` only if every
/// step succeeded.
pub fn write_atomic(
    target: &Path,
    fill: impl FnOnce(&mut BufWriter<Output>) -> anyhow::Result<()>,
) -> Result<(), WriteError> {
    let mut batch = Batch::new();
    batch.add(target, fill)?;
    batch.commit()
}

/// [`write_atomic`] of a byte string.
pub fn write_bytes_atomic(target: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let mut batch = Batch::new();
    batch.add_bytes(target, bytes)?;
    batch.commit()
}

/// Writes the folder `target` whole or not at all: `fill` writes every file into a
/// staging folder beside it, which then takes `target`'s place (the previous folder moved
/// aside and removed). A failure removes the staging folder and leaves `target` as it
/// was. For outputs that own their whole folder (the demo's report).
pub fn replace_folder<T>(
    target: &Path,
    fill: impl FnOnce(&Path) -> anyhow::Result<T>,
) -> Result<T, WriteError> {
    let staging = temporary_beside(target, "part");
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir_all(&staging).map_err(WriteError::io("create", &staging))?;
    let filled = match fill(&staging) {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(WriteError::Content(e));
        }
    };
    let old = temporary_beside(target, "old");
    let had = target.exists();
    let swapped = (|| {
        if had {
            std::fs::rename(target, &old).map_err(WriteError::io("move aside", target))?;
        }
        std::fs::rename(&staging, target).map_err(|e| {
            if had {
                let _ = std::fs::rename(&old, target);
            }
            WriteError::io("move into place", target)(e)
        })
    })();
    if let Err(e) = swapped {
        let _ = std::fs::remove_dir_all(&staging);
        return Err(e);
    }
    if had {
        let _ = std::fs::remove_dir_all(&old);
    }
    Ok(filled)
}

/// A file written bit by bit under a temporary name beside its target, moved into place
/// by [`PendingFile::commit`]; dropped uncommitted (an error on the way), it is removed and
/// the target is left as it was.
pub struct PendingFile {
    target: PathBuf,
    tmp: PathBuf,
    writer: Option<BufWriter<Output>>,
}

impl PendingFile {
    /// Starts writing `target`.
    pub fn create(target: &Path) -> Result<Self, WriteError> {
        let target = output_target(target)?;
        let tmp = temporary_beside(&target, "part");
        Ok(Self {
            target,
            writer: Some(BufWriter::with_capacity(1 << 16, Output::create(&tmp)?)),
            tmp,
        })
    }

    /// Appends `bytes`.
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), WriteError> {
        // The writer is taken only by the commit, which consumes the file.
        let Some(w) = self.writer.as_mut() else {
            return Ok(());
        };
        w.write_all(bytes)
            .map_err(WriteError::io("write", &self.target))
    }

    /// Flushes, syncs and renames the file into place.
    pub fn commit(self) -> Result<(), WriteError> {
        self.commit_by(|tmp, target| {
            std::fs::rename(tmp, target).map_err(WriteError::io("move into place", target))
        })
    }

    /// Flushes, syncs and puts the file into place only where no file is: whether it
    /// did. Never replaces a file, even one that appears meanwhile (a hard link, which
    /// fails on an existing name; where the file system has none, a rename after a look).
    pub fn commit_if_new(self) -> Result<bool, WriteError> {
        let mut placed = false;
        self.commit_by(|tmp, target| {
            let linked = match std::fs::hard_link(tmp, target) {
                Ok(()) => Ok(true),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(false),
                Err(_) if target.exists() => Ok(false),
                Err(_) => std::fs::rename(tmp, target).map(|()| true),
            };
            placed = linked.map_err(WriteError::io("place", target))?;
            Ok(())
        })?;
        Ok(placed)
    }

    /// Flushes and syncs the file, then `place(temporary, target)`; the temporary is
    /// removed in every case.
    fn commit_by(
        mut self,
        place: impl FnOnce(&Path, &Path) -> Result<(), WriteError>,
    ) -> Result<(), WriteError> {
        // The writer is there until this, which consumes the file, takes it.
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let result = finish(writer, &self.target).and_then(|()| place(&self.tmp, &self.target));
        let _ = std::fs::remove_file(&self.tmp);
        result
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Refuses an image output not named `.png` (images are written as PNG only): call it
/// before the work, as [`write_png`] does before writing.
pub fn require_png_name(target: &Path) -> Result<(), WriteError> {
    if target
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        return Ok(());
    }
    invalid!(
        "{}: images are written as PNG; name the file .png",
        target.display()
    )
}

/// PNG sample layouts written by [`write_png`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PngLayout {
    /// One 8-bit sample per pixel.
    Gray8,
    /// Three interleaved 8-bit samples per pixel.
    Rgb8,
    /// One 16-bit sample per pixel (native-endian `u16` values given as bytes).
    Gray16,
    /// Three interleaved 16-bit samples per pixel.
    Rgb16,
}

impl PngLayout {
    /// The layout for `channels` (1 or 3) samples of `bits` (8 or 16).
    pub fn new(channels: usize, bits: u8) -> Result<Self, WriteError> {
        Ok(match (channels, bits) {
            (1, 8) => Self::Gray8,
            (3, 8) => Self::Rgb8,
            (1, 16) => Self::Gray16,
            (3, 16) => Self::Rgb16,
            _ => {
                invalid!(
                    "PNG output is gray or RGB of 8 or 16 bits, not {channels} channels of {bits} bits"
                );
            }
        })
    }

    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::Gray8 => 1,
            Self::Rgb8 => 3,
            Self::Gray16 => 2,
            Self::Rgb16 => 6,
        }
    }

    fn color(self) -> image::ExtendedColorType {
        match self {
            Self::Gray8 => image::ExtendedColorType::L8,
            Self::Rgb8 => image::ExtendedColorType::Rgb8,
            Self::Gray16 => image::ExtendedColorType::L16,
            Self::Rgb16 => image::ExtendedColorType::Rgb16,
        }
    }
}

/// Writes a `width × height` PNG whole or not at all ([`write_atomic`]); `data` holds the
/// samples row by row in `layout`.
pub fn write_png(
    target: &Path,
    data: &[u8],
    size: (usize, usize),
    layout: PngLayout,
) -> Result<(), WriteError> {
    let mut batch = Batch::new();
    add_png(&mut batch, target, data, size, layout)?;
    batch.commit()
}

/// [`write_png`] into a [`Batch`].
pub fn add_png(
    batch: &mut Batch,
    target: &Path,
    data: &[u8],
    size: (usize, usize),
    layout: PngLayout,
) -> Result<(), WriteError> {
    require_png_name(target)?;
    batch.add(target, |out| {
        encode_png(out, data, size, layout).map_err(|e| {
            anyhow::Error::from(e).context(format!("cannot write {}", target.display()))
        })
    })
}

/// Encodes a `width × height` PNG of `data` (samples row by row in `layout`) into `out`.
pub fn encode_png(
    out: impl Write,
    data: &[u8],
    (width, height): (usize, usize),
    layout: PngLayout,
) -> Result<(), WriteError> {
    use image::ImageEncoder;
    let sized = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(layout.bytes_per_pixel()))
        == Some(data.len());
    let (Ok(w), Ok(h), true) = (u32::try_from(width), u32::try_from(height), sized) else {
        invalid!(
            "{} bytes are not a {width}×{height} image of {layout:?}",
            data.len()
        );
    };
    image::codecs::png::PngEncoder::new(out)
        .write_image(data, w, h, layout.color())
        .map_err(|e| match e {
            // Kept as the cause itself: the encoder's wrapper hides it from `source()`,
            // and a full disk must be found among the causes.
            image::ImageError::IoError(io) => WriteError::Content(io.into()),
            other => WriteError::Content(other.into()),
        })
}

/// Fails early, with the path in the message, if `path` cannot be written, before any
/// long work starts: its folder, or the nearest one above it that exists (the missing ones
/// are made as the output is written: [`NewFolder::for_file`]), must be a folder that can
/// be written to. Leaves an existing file as it is and creates nothing.
pub fn check_writable(path: &Path) -> Result<(), WriteError> {
    let parent = folder_of(path);
    let existing = parent
        .ancestors()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .find(|p| p.exists())
        .unwrap_or(Path::new("."));
    if !existing.is_dir() {
        invalid!(
            "cannot write {}: {} is not a folder",
            path.display(),
            existing.display()
        );
    }
    let probe = if path.exists() {
        std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .map(|_| ())
    } else {
        let tmp = existing.join(format!(".rollfuse-write-check-{}", std::process::id()));
        std::fs::File::create(&tmp).and_then(|_| std::fs::remove_file(&tmp))
    };
    probe.map_err(WriteError::io("write", path))
}

/// Removes files an output no longer has (a replaced strip's extra segments, another
/// output's side files), naming the first that cannot be removed.
pub fn remove_stale(paths: Vec<PathBuf>) -> Result<(), WriteError> {
    for p in paths {
        std::fs::remove_file(&p).map_err(WriteError::io("remove the stale", &p))?;
    }
    Ok(())
}

/// The folder `path` is in (`.` for a bare name).
pub fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_error_says_whose_fault_it_is() {
        let dir = tempfile::tempdir().unwrap();
        // The file system's: the folder is not there.
        let missing = dir.path().join("no/such/folder/out.bin");
        let e = write_bytes_atomic(&missing, b"x").unwrap_err();
        assert!(
            matches!(
                e,
                WriteError::Io {
                    doing: "create",
                    ..
                }
            ),
            "{e:?}"
        );
        assert_eq!(e.io_kind(), Some(std::io::ErrorKind::NotFound));
        // Where it was pointed: a folder is not replaced by a file.
        let e = write_bytes_atomic(dir.path(), b"x").unwrap_err();
        assert!(matches!(e, WriteError::Refused(_)), "{e:?}");
        assert_eq!(e.io_kind(), None);
        // A full disk met by the code writing the content is told apart from its own
        // errors, and the target keeps what it had.
        let out = dir.path().join("out.bin");
        std::fs::write(&out, b"old").unwrap();
        let full = write_atomic(&out, |_| {
            Err(std::io::Error::from(std::io::ErrorKind::StorageFull).into())
        })
        .unwrap_err();
        assert_eq!(full.io_kind(), Some(std::io::ErrorKind::StorageFull));
        let own = write_atomic(&out, |_| anyhow::bail!("no pixels")).unwrap_err();
        assert!(matches!(own, WriteError::Content(_)) && own.io_kind().is_none());
        assert_eq!(std::fs::read(&out).unwrap(), b"old");
    }

    #[test]
    fn a_link_is_written_through_and_special_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.json");
        std::fs::write(&real, b"old").unwrap();
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink("real.json", &link).unwrap();
        write_bytes_atomic(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
        // A link to a file not there yet makes it.
        let dangling = dir.path().join("dangling.json");
        std::os::unix::fs::symlink("made.json", &dangling).unwrap();
        write_bytes_atomic(&dangling, b"made").unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("made.json")).unwrap(),
            b"made"
        );
        // A folder, a device, a FIFO and a loop of links are not files to replace.
        let err = write_bytes_atomic(dir.path(), b"x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("is a folder"), "{err}");
        let err = write_bytes_atomic(Path::new("/dev/null"), b"x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("is a device"), "{err}");
        let fifo = dir.path().join("fifo");
        if std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .is_ok_and(|s| s.success())
        {
            let err = write_bytes_atomic(&fifo, b"x").unwrap_err().to_string();
            assert!(err.contains("is a FIFO"), "{err}");
        }
        let a = dir.path().join("a");
        std::os::unix::fs::symlink("b", &a).unwrap();
        std::os::unix::fs::symlink("a", dir.path().join("b")).unwrap();
        let err = write_bytes_atomic(&a, b"x").unwrap_err().to_string();
        assert!(err.contains("loop of symbolic links"), "{err}");
    }

    #[test]
    fn temporaries_name_their_owner() {
        let t = temporary_beside(Path::new("out/strip.0003.png"), "part");
        let name = t.file_name().unwrap().to_str().unwrap();
        assert_eq!(temporary_owner(name), Some(std::process::id()));
        assert_eq!(temporary_owner(".strip.0001.png.new-77-4.png"), Some(77));
        for other in [
            "strip.png",
            ".strip.png",
            ".x.part-1",
            ".x.mine-1-2",
            ".x.part--2",
        ] {
            assert_eq!(temporary_owner(other), None, "{other}");
        }
    }

    #[test]
    fn stale_temporaries_of_processes_gone_are_swept_and_others_kept() {
        let dir = tempfile::tempdir().unwrap();
        // No process has an id this high (Linux's limit is 2²²).
        let gone = [".a.png.part-999999999-0", ".b.png.new-999999999-3.png"];
        for name in gone {
            std::fs::write(dir.path().join(name), b"debris").unwrap();
        }
        std::fs::create_dir(dir.path().join(".report.part-999999999-1")).unwrap();
        let live = format!(".c.png.part-{}-0", std::process::id());
        for name in [live.as_str(), ".d.png.part-1-0", "e.png", ".hidden"] {
            std::fs::write(dir.path().join(name), b"keep").unwrap();
        }
        if !Path::new("/proc/self").exists() {
            assert_eq!(sweep_stale(dir.path()), 0);
            return;
        }
        assert_eq!(sweep_stale(dir.path()), 3);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        // Process 1 (init) runs; this process runs.
        let mut want = vec![
            live,
            ".d.png.part-1-0".into(),
            ".hidden".into(),
            "e.png".into(),
        ];
        want.sort();
        assert_eq!(left, want);
    }

    #[test]
    fn a_failed_write_keeps_the_previous_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        write_bytes_atomic(&target, b"good").unwrap();
        let err = write_atomic(&target, |w| {
            w.write_all(b"half")?;
            anyhow::bail!("the disk is full")
        })
        .unwrap_err();
        assert!(err.to_string().contains("disk is full"), "{err}");
        assert_eq!(std::fs::read(&target).unwrap(), b"good");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "a temporary was left behind");
    }

    #[test]
    fn png_sizes_that_do_not_match_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("x.png");
        assert!(write_png(&target, &[0; 5], (2, 2), PngLayout::Gray8).is_err());
        assert!(!target.exists());
        write_png(&target, &[0, 64, 128, 255], (2, 2), PngLayout::Gray8).unwrap();
        let back = image::open(&target).unwrap().to_luma8().into_raw();
        assert_eq!(back, [0, 64, 128, 255]);
    }
}
