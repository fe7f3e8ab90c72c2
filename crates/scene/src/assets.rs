//! Reading the files a scene file refers to: glTF buffers and images (the glTF 2.0
//! specification, section "URIs": a URI is a data URI or a path relative to the glTF file;
//! absolute paths and other schemes are components a client *may* support), OBJ material
//! libraries (`mtllib`) and their textures (`map_Kd`, Wavefront MTL).
//!
//! Rules, for every load:
//!
//! * **The asset's folder.** A referenced path is resolved against the folder of the scene file
//!   and then canonicalized (`..`, `.` and symbolic links followed). It must lie inside that
//!   folder, or inside one of [`LoadOptions::allowed_roots`]; a path that leads outside them
//!   (absolute, a `../` that climbs out, or a link that points out) is refused, naming the
//!   reference and where it leads.
//! * **Regular files only.** A file's metadata is checked before it is opened (which does not
//!   open it, so a FIFO cannot block the load); directories, FIFOs, sockets and devices such as
//!   `/dev/zero` are refused. On Unix the file is then opened non-blocking and checked again,
//!   so one swapped for a FIFO in between cannot block either.
//! * **Bounded reads.** A read never takes more bytes than the metadata reported (and no more
//!   than its caller needs, e.g. a glTF buffer's `byteLength`). Each file is read once per
//!   load however often it is named, unless a later reference needs more of it than was read.
//! * **A total.** The bytes one load may read, the scene file included, are capped by
//!   [`LoadOptions::max_total_bytes`]; by default the cap is
//!   [`DEFAULT_BUDGET_FACTOR`] × the sizes of the distinct files involved +
//!   [`DEFAULT_BUDGET_BASE`].
//! * **A total of what is made from them.** A few bytes can ask for much more than they
//!   hold: a glTF file can point a million meshes at one big accessor or images at one
//!   small file that decodes to a gigabyte, or reach one node (its name, its camera, its
//!   animation curves) along a million paths. What a load decodes and copies (a glTF
//!   file's accessors, images and what copies of a node repeat; an OBJ's textures) is capped
//!   by [`LoadOptions::max_decoded_bytes`]; by default by [`DEFAULT_DECODE_FACTOR`] × the
//!   bytes it reads (the scene file included) + [`DEFAULT_BUDGET_BASE`]. Past the cap a
//!   texture is skipped with a warning (it is not decoded); anything else fails the load.
//!
//! The files a user names outside a scene (a camera path, a walk's reports, the GIFs and
//! frames a merge joins) follow the regular-file rule through [`read_regular_file`] (whole,
//! at most a given size) and [`open_regular_file`] (streamed).

use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::fs::Metadata;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// How a scene load may reach outside its own file.
///
/// ```
/// use sightline_scene::LoadOptions;
/// let opts = LoadOptions::default().allow_root("/srv/shared-textures").max_total_bytes(1 << 30);
/// assert_eq!(opts.allowed_roots.len(), 1);
/// ```
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Folders besides the scene file's own whose files (and subfolders' files) a scene may
    /// refer to. Each must exist; it is canonicalized when the load starts.
    pub allowed_roots: Vec<PathBuf>,
    /// The most bytes one load may read from files, the scene file included. `None`: a
    /// generous default of [`DEFAULT_BUDGET_FACTOR`] × the sizes of the distinct files
    /// involved + [`DEFAULT_BUDGET_BASE`].
    pub max_total_bytes: Option<u64>,
    /// The most scene nodes one load may create. A glTF node reached along several paths
    /// (a shared subgraph) becomes one copy per path, so a small file can ask for very many;
    /// past this count the load fails, naming the limit. `None`: [`DEFAULT_MAX_NODES`].
    pub max_nodes: Option<usize>,
    /// The most bytes of scene data one load may make from its files: decoded images (4
    /// bytes a texel; for an OBJ, only these are counted), and for a glTF file decoded
    /// accessors (4 bytes a component, once per primitive or animation sampler naming
    /// them), index lists made from strips, fans and unindexed primitives, a mesh's name kept
    /// with each of its primitives, and what each copy of a shared node repeats (its name,
    /// its camera's name, the curves animating it). A file can make one accessor decode for
    /// every mesh that names it, or one node load once per path to it. Past this total a
    /// texture is skipped with a warning, anything else fails the load, naming the limit.
    /// `None`: [`DEFAULT_DECODE_FACTOR`] × the bytes the load reads (the scene file
    /// included, also a glTF file given as bytes) + [`DEFAULT_BUDGET_BASE`].
    pub max_decoded_bytes: Option<u64>,
}

impl LoadOptions {
    /// Also allows files under `dir`.
    pub fn allow_root(mut self, dir: impl Into<PathBuf>) -> Self {
        self.allowed_roots.push(dir.into());
        self
    }

    /// Caps the bytes one load may read.
    pub fn max_total_bytes(mut self, bytes: u64) -> Self {
        self.max_total_bytes = Some(bytes);
        self
    }

    /// Caps the scene nodes one load may create.
    pub fn max_nodes(mut self, nodes: usize) -> Self {
        self.max_nodes = Some(nodes);
        self
    }

    /// Caps the bytes of scene data one load may decode and copy.
    pub fn max_decoded_bytes(mut self, bytes: u64) -> Self {
        self.max_decoded_bytes = Some(bytes);
        self
    }
}

/// The default cap on the nodes one load may create (see [`LoadOptions::max_nodes`]).
pub const DEFAULT_MAX_NODES: usize = 1 << 20;

/// The default total-read cap is this many times the sizes of the files involved…
pub const DEFAULT_BUDGET_FACTOR: u64 = 4;
/// …plus this many bytes.
pub const DEFAULT_BUDGET_BASE: u64 = 64 << 20;
/// The default cap on decoded data is this many times the bytes a load reads (plus
/// [`DEFAULT_BUDGET_BASE`]): room for every accessor decoded once (a u8 index of a triangle
/// strip takes 4 bytes decoded and 12 as triangles) and for sharing (a vertex set named by
/// the primitives of a multi-material mesh is kept once per primitive).
pub const DEFAULT_DECODE_FACTOR: u64 = 32;

/// Why a referenced file was not read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum AssetError {
    /// The file is missing, unreadable, malformed or of an unsupported kind: a texture or a
    /// material library is then skipped with a warning.
    Unavailable(String),
    /// The rules above forbid reading it: always an error.
    Refused(String),
}

impl AssetError {
    /// The same kind with a prefix on the message.
    pub(crate) fn context(self, prefix: impl std::fmt::Display) -> Self {
        match self {
            AssetError::Unavailable(m) => AssetError::Unavailable(format!("{prefix}: {m}")),
            AssetError::Refused(m) => AssetError::Refused(format!("{prefix}: {m}")),
        }
    }
}

impl From<AssetError> for String {
    fn from(e: AssetError) -> String {
        match e {
            AssetError::Unavailable(m) | AssetError::Refused(m) => m,
        }
    }
}

/// A message for an I/O error, with "file not found" spelled out.
pub(crate) fn io_why(what: &str, e: &std::io::Error) -> String {
    if e.kind() == std::io::ErrorKind::NotFound {
        format!("{what}: file not found")
    } else {
        format!("{what}: {e}")
    }
}

/// What kind of non-regular file `meta` describes, for messages.
fn kind_of(meta: &Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// Checks that `meta` describes a regular file.
fn check_regular(meta: &Metadata) -> Result<(), String> {
    if meta.is_file() {
        Ok(())
    } else {
        Err(format!("is not a regular file ({}); only regular files are read", kind_of(meta)))
    }
}

/// Opens a file known (from its metadata) to be regular, without blocking if it has been
/// replaced by a FIFO since, and checks it again through the open handle.
fn open_regular(path: &Path) -> Result<std::fs::File, AssetError> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    let f = o.open(path).map_err(|e| AssetError::Unavailable(io_why("cannot open", &e)))?;
    let meta = f.metadata().map_err(|e| AssetError::Unavailable(io_why("cannot read its metadata", &e)))?;
    check_regular(&meta).map_err(AssetError::Refused)?;
    Ok(f)
}

/// Reads at most `n` bytes of `f`.
fn read_at_most(f: std::fs::File, n: u64) -> Result<Vec<u8>, String> {
    // Reserve what the metadata promised, but not so much that a lying size allocates before
    // a byte arrives.
    let mut out = Vec::with_capacity(n.min(64 << 20) as usize);
    f.take(n).read_to_end(&mut out).map_err(|e| io_why("cannot read", &e))?;
    Ok(out)
}

/// Opens a file named by a user for reading, when it is a regular file: a FIFO, socket or
/// device is refused, from its metadata before the open (so one that the metadata shows is
/// not opened at all) and again through the open handle, opened non-blocking (so a file
/// swapped for a FIFO in between cannot block the open or the reads). For readers that
/// stream a file rather than take its bytes (a GIF decoder, a copy); the error says what is
/// wrong, for the caller to prefix with its name.
pub fn open_regular_file(path: &Path) -> Result<std::fs::File, String> {
    regular_size(path)?;
    open_regular(path).map_err(String::from)
}

/// Reads a whole file named by a user (a camera path, a report) under the rules the scene
/// files follow: a regular file only (a FIFO, socket or device is refused and never
/// blocks the read), no more bytes than its size, and at most `max_bytes`. The error
/// says what is wrong with the file, for the caller to prefix with its name.
pub fn read_regular_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>, String> {
    let len = regular_size(path)?;
    if len > max_bytes {
        return Err(format!("is {len} bytes, more than the {max_bytes} read of such a file"));
    }
    read_at_most(open_regular(path).map_err(String::from)?, len)
}

/// The size of a regular file, from its metadata (which does not open it, so a FIFO cannot
/// block); an error for anything else.
fn regular_size(path: &Path) -> Result<u64, String> {
    let meta = std::fs::metadata(path).map_err(|e| io_why("cannot read", &e))?;
    check_regular(&meta)?;
    Ok(meta.len())
}

/// Canonical path → (the bytes read of it, the size of the whole file).
type FileCache = HashMap<PathBuf, (Arc<[u8]>, u64)>;

/// The files of one load: the rules in the module documentation, and a cache so each file is
/// read once. Methods take `&self` (the state is in cells) so loaders can call them from
/// closures and shared borrows.
pub(crate) struct AssetReader {
    /// The scene file, as given.
    main: PathBuf,
    /// Its folder, as given (references are joined to this).
    folder: PathBuf,
    /// Its folder canonicalized, once needed.
    canon_folder: RefCell<Option<Result<PathBuf, String>>>,
    /// The extra allowed roots, canonicalized.
    roots: Vec<PathBuf>,
    /// Sizes of the distinct files seen (stat'ed) so far, for the default read cap.
    seen_bytes: Cell<u64>,
    /// Bytes read ([`LoadOptions::max_total_bytes`]).
    reads: Cap,
    /// The size of a scene file given in memory (not read through this reader).
    given_bytes: Cell<u64>,
    /// Bytes decoded and copied ([`LoadOptions::max_decoded_bytes`]).
    decoded: Cap,
    files: RefCell<FileCache>,
}

/// One of a load's caps: the bytes counted so far, and the limit the options give (else a
/// default the caller works out, which grows as the load goes).
struct Cap {
    explicit: Option<u64>,
    used: Cell<u64>,
}

impl Cap {
    fn new(explicit: Option<u64>) -> Cap {
        Cap { explicit, used: Cell::new(0) }
    }

    /// The limit: the one given, else `default`.
    fn limit(&self, default: impl FnOnce() -> u64) -> u64 {
        self.explicit.unwrap_or_else(default)
    }

    /// Counts `n` more bytes if the total stays within the limit; else leaves the count and
    /// returns the total it would reach and the limit.
    fn take(&self, n: u64, default: impl FnOnce() -> u64) -> Result<(), (u64, u64)> {
        let (limit, total) = (self.limit(default), self.used.get().saturating_add(n));
        if total > limit {
            return Err((total, limit));
        }
        self.used.set(total);
        Ok(())
    }
}

impl AssetReader {
    /// The reader for a load of `main` (which need not exist when only its folder is used, as
    /// for bytes already in memory). Fails when an allowed root cannot be resolved.
    pub(crate) fn new(main: &Path, opts: &LoadOptions) -> Result<Self, String> {
        let folder = match main.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let roots = opts
            .allowed_roots
            .iter()
            .map(|r| {
                let c = std::fs::canonicalize(r)
                    .map_err(|e| io_why(&format!("allowed asset root {}: cannot resolve it", r.display()), &e))?;
                if !c.is_dir() {
                    return Err(format!("allowed asset root {} is not a directory", r.display()));
                }
                Ok(c)
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(AssetReader {
            main: main.to_path_buf(),
            folder,
            canon_folder: RefCell::new(None),
            roots,
            seen_bytes: Cell::new(0),
            reads: Cap::new(opts.max_total_bytes),
            given_bytes: Cell::new(0),
            decoded: Cap::new(opts.max_decoded_bytes),
            files: RefCell::new(HashMap::new()),
        })
    }

    /// The default total-read cap now (it grows with the files seen).
    fn default_limit(&self) -> u64 {
        DEFAULT_BUDGET_BASE.saturating_add(self.seen_bytes.get().saturating_mul(DEFAULT_BUDGET_FACTOR))
    }

    /// The total-read cap now.
    #[cfg(test)]
    fn limit(&self) -> u64 {
        self.reads.limit(|| self.default_limit())
    }

    /// Charges `n` bytes about to be read from `what` against the cap.
    fn charge(&self, n: u64, what: &str) -> Result<(), AssetError> {
        if let Err((total, limit)) = self.reads.take(n, || self.default_limit()) {
            let how = match self.reads.explicit {
                Some(_) => "the limit set in the load options".to_string(),
                None => format!(
                    "the default limit, {DEFAULT_BUDGET_FACTOR} × the size of the files involved + {} MiB",
                    DEFAULT_BUDGET_BASE >> 20
                ),
            };
            return Err(AssetError::Refused(format!(
                "reading {n} bytes of {what} would bring this load to {total} bytes, over its limit of {limit} bytes on total reads ({how})"
            )));
        }
        Ok(())
    }

    /// Counts a scene file given in memory (not read through this reader) among the bytes
    /// the default decoded-data cap grows with (the cap on reads is not changed).
    pub(crate) fn given_main(&self, len: u64) {
        self.given_bytes.set(self.given_bytes.get().saturating_add(len));
    }

    /// The default decoded-data cap now (it grows with the bytes read: what a file merely
    /// names, read or not, does not raise it).
    fn default_decode_limit(&self) -> u64 {
        let input = self.reads.used.get().saturating_add(self.given_bytes.get());
        DEFAULT_BUDGET_BASE.saturating_add(input.saturating_mul(DEFAULT_DECODE_FACTOR))
    }

    /// The decoded-data cap now.
    #[cfg(test)]
    fn decode_limit(&self) -> u64 {
        self.decoded.limit(|| self.default_decode_limit())
    }

    /// Charges `n` bytes about to be decoded or copied for `what` against the cap; the error
    /// names `what`, the totals and the option that sets the cap.
    pub(crate) fn charge_decoded(&self, n: u64, what: impl std::fmt::Display) -> Result<(), String> {
        if let Err((total, limit)) = self.decoded.take(n, || self.default_decode_limit()) {
            let how = match self.decoded.explicit {
                Some(_) => "LoadOptions::max_decoded_bytes".to_string(),
                None => format!(
                    "the default limit, {DEFAULT_DECODE_FACTOR} × the bytes read + {} MiB; \
                     LoadOptions::max_decoded_bytes sets another",
                    DEFAULT_BUDGET_BASE >> 20
                ),
            };
            return Err(format!(
                "{what} would bring the data this load decodes and copies to {total} bytes, \
                 over its limit of {limit} bytes ({how})"
            ));
        }
        Ok(())
    }

    /// Bytes read so far by this load.
    #[cfg(test)]
    pub(crate) fn bytes_read(&self) -> u64 {
        self.reads.used.get()
    }

    /// Checks and reads the scene file itself (not subject to the folder rule).
    pub(crate) fn read_main(&self) -> Result<Vec<u8>, String> {
        let f = self.open_main()?;
        let n = f.limit();
        read_at_most(f.into_inner(), n)
    }

    /// Checks the scene file, charges its size and opens it for reading at most that size.
    pub(crate) fn open_main(&self) -> Result<std::io::Take<std::fs::File>, String> {
        let len = regular_size(&self.main)?;
        self.seen_bytes.set(self.seen_bytes.get().saturating_add(len));
        self.charge(len, "the scene file").map_err(String::from)?;
        Ok(open_regular(&self.main).map_err(String::from)?.take(len))
    }

    /// The asset folder, canonicalized.
    fn canon_folder(&self) -> Result<PathBuf, AssetError> {
        let mut slot = self.canon_folder.borrow_mut();
        let r = slot.get_or_insert_with(|| {
            std::fs::canonicalize(&self.folder)
                .map_err(|e| io_why(&format!("cannot resolve the asset folder {}", self.folder.display()), &e))
        });
        r.clone().map_err(AssetError::Refused)
    }

    /// Resolves a reference (relative to the asset folder, or absolute) to a canonical path
    /// inside the asset folder or an allowed root.
    pub(crate) fn resolve(&self, reference: &Path) -> Result<PathBuf, AssetError> {
        let joined = self.folder.join(reference);
        // `canonicalize` follows links with `realpath`, which does not open the file.
        let canon = std::fs::canonicalize(&joined).map_err(|e| AssetError::Unavailable(io_why("cannot read", &e)))?;
        let folder = self.canon_folder()?;
        if canon.starts_with(&folder) || self.roots.iter().any(|r| canon.starts_with(r)) {
            return Ok(canon);
        }
        let mut allowed = format!("the asset folder {}", folder.display());
        for r in &self.roots {
            allowed.push_str(&format!(", {}", r.display()));
        }
        let how = if reference.is_absolute() {
            "an absolute path"
        } else if reference.components().any(|c| c == std::path::Component::ParentDir) {
            "'..' climbs out of it"
        } else {
            "a symbolic link leads out of it"
        };
        Err(AssetError::Refused(format!(
            "resolves to {}, outside the asset folder ({how}); files are read only from {allowed} unless another root is allowed explicitly",
            canon.display()
        )))
    }

    /// Reads the first `want` bytes (or all, if shorter) of the resolved file `canon`; a file
    /// larger than `max_file` is not read. Returns the bytes (possibly more than `want` when the
    /// file was read further before) and the file's size. Each file is read once per load,
    /// unless a later caller wants more of it than was read.
    pub(crate) fn read(&self, canon: &Path, want: u64, max_file: u64) -> Result<(Arc<[u8]>, u64), AssetError> {
        if let Some((bytes, size)) = self.files.borrow().get(canon) {
            if bytes.len() as u64 >= want.min(*size) {
                return Ok((bytes.clone(), *size));
            }
        }
        let meta = std::fs::metadata(canon).map_err(|e| AssetError::Unavailable(io_why("cannot read", &e)))?;
        check_regular(&meta).map_err(AssetError::Refused)?;
        let size = meta.len();
        if size > max_file {
            // Not read; a texture is then skipped with a warning, like an undecodable one.
            return Err(AssetError::Unavailable(format!(
                "is {size} bytes, over the limit of {max_file} bytes for this kind of file"
            )));
        }
        if !self.files.borrow().contains_key(canon) {
            self.seen_bytes.set(self.seen_bytes.get().saturating_add(size));
        }
        let n = want.min(size);
        self.charge(n, &canon.display().to_string())?;
        let f = open_regular(canon)?;
        let bytes: Arc<[u8]> = read_at_most(f, n).map_err(AssetError::Unavailable)?.into();
        self.files.borrow_mut().insert(canon.to_path_buf(), (bytes.clone(), size));
        Ok((bytes, size))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch folder with an empty `asset/` inside, removed when dropped.
    fn fresh(test: &str) -> tempfile::TempDir {
        let d = tempfile::Builder::new().prefix(&format!("sightline-assets-{test}-")).tempdir().unwrap();
        std::fs::create_dir_all(d.path().join("asset")).unwrap();
        d
    }

    #[test]
    fn a_file_named_many_ways_is_read_once() {
        let d = fresh("once");
        std::fs::write(d.path().join("asset/a.bin"), [7u8; 1000]).unwrap();
        let r = AssetReader::new(&d.path().join("asset/scene.gltf"), &LoadOptions::default()).unwrap();
        for name in ["a.bin", "./a.bin", "../asset/a.bin", "a.bin"] {
            let f = r.resolve(Path::new(name)).unwrap();
            let (bytes, size) = r.read(&f, 100, u64::MAX).unwrap();
            assert_eq!((bytes.len(), size), (100, 1000), "{name}");
        }
        assert_eq!(r.bytes_read(), 100);
        // Wanting more reads further (once), never past the file's size.
        let f = r.resolve(Path::new("a.bin")).unwrap();
        assert_eq!(r.read(&f, u64::MAX, u64::MAX).unwrap().0.len(), 1000);
        assert_eq!(r.read(&f, 500, u64::MAX).unwrap().0.len(), 1000);
        assert_eq!(r.bytes_read(), 1100);
    }

    #[test]
    fn the_default_cap_grows_with_the_files_and_an_explicit_one_does_not() {
        let d = fresh("cap");
        std::fs::write(d.path().join("asset/a.bin"), [1u8; 5000]).unwrap();
        let r = AssetReader::new(&d.path().join("asset/x.obj"), &LoadOptions::default()).unwrap();
        assert_eq!(r.limit(), DEFAULT_BUDGET_BASE);
        let f = r.resolve(Path::new("a.bin")).unwrap();
        r.read(&f, u64::MAX, u64::MAX).unwrap();
        assert_eq!(r.limit(), DEFAULT_BUDGET_BASE + DEFAULT_BUDGET_FACTOR * 5000);
        let r = AssetReader::new(&d.path().join("asset/x.obj"), &LoadOptions::default().max_total_bytes(4999)).unwrap();
        let e = r.read(&f, u64::MAX, u64::MAX).unwrap_err();
        assert!(matches!(&e, AssetError::Refused(m) if m.contains("limit of 4999 bytes")), "{e:?}");
        assert_eq!(r.bytes_read(), 0);
    }

    #[test]
    fn the_default_decode_cap_grows_with_the_bytes_read_and_given() {
        let d = fresh("decode-cap");
        std::fs::write(d.path().join("asset/a.bin"), [1u8; 5000]).unwrap();
        let r = AssetReader::new(&d.path().join("asset/x.gltf"), &LoadOptions::default()).unwrap();
        assert_eq!(r.decode_limit(), DEFAULT_BUDGET_BASE);
        r.given_main(100);
        assert_eq!(r.decode_limit(), DEFAULT_BUDGET_BASE + DEFAULT_DECODE_FACTOR * 100);
        assert_eq!(r.limit(), DEFAULT_BUDGET_BASE, "a scene given in memory leaves the read cap alone");
        // Only what is read counts, not the size of the file named.
        let f = r.resolve(Path::new("a.bin")).unwrap();
        r.read(&f, 1000, u64::MAX).unwrap();
        assert_eq!(r.decode_limit(), DEFAULT_BUDGET_BASE + DEFAULT_DECODE_FACTOR * 1100);
        // Charges add up to the cap, and one past it is refused without being counted.
        let cap = r.decode_limit();
        r.charge_decoded(cap - 10, "most").unwrap();
        r.charge_decoded(10, "the rest").unwrap();
        let e = r.charge_decoded(1, "one more byte").unwrap_err();
        assert!(e.starts_with("one more byte would bring") && e.contains(&format!("{}", cap + 1)), "{e}");
        assert_eq!(r.decoded.used.get(), cap);
        let r = AssetReader::new(&d.path().join("asset/x.gltf"), &LoadOptions::default().max_decoded_bytes(7)).unwrap();
        r.given_main(1 << 20);
        assert_eq!(r.decode_limit(), 7);
        assert!(r.charge_decoded(8, "eight").unwrap_err().contains("LoadOptions::max_decoded_bytes"));
    }

    #[test]
    fn a_file_over_its_kind_limit_is_not_read() {
        let d = fresh("kind");
        std::fs::write(d.path().join("asset/big.png"), [0u8; 300]).unwrap();
        let r = AssetReader::new(&d.path().join("asset/x.gltf"), &LoadOptions::default()).unwrap();
        let f = r.resolve(Path::new("big.png")).unwrap();
        let e = r.read(&f, u64::MAX, 200).unwrap_err();
        assert!(matches!(&e, AssetError::Unavailable(m) if m.contains("300 bytes")), "{e:?}");
        assert_eq!(r.bytes_read(), 0);
    }

    /// The check on the open handle alone (what catches a file swapped for a FIFO after its
    /// metadata was read): a FIFO is opened without blocking and refused.
    #[cfg(unix)]
    #[test]
    fn a_fifo_reaching_the_open_is_refused_without_blocking() {
        let d = fresh("fifo");
        let fifo = d.path().join("asset/fifo");
        if !std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            eprintln!("skipped: cannot make a FIFO with mkfifo");
            return;
        }
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let _ = tx.send(open_regular(&fifo).map(|_| ()));
        });
        let e = rx.recv_timeout(std::time::Duration::from_secs(30)).expect("opening a FIFO blocked").unwrap_err();
        assert!(matches!(&e, AssetError::Refused(m) if m.contains("not a regular file")), "{e:?}");
    }
}
