//! A glTF's external files: where its buffer and image URIs may point, and reading them.
//!
//! **The read rule.** A URI is a relative reference (glTF 2.0 §3.1: "relative paths … to the
//! glTF file"), percent-decoded (RFC 3986 §2.1; the result must be UTF-8 without NUL), or a
//! `data:` URI (base64 only). It names a *regular file* that, with every symbolic link
//! resolved, lies inside the scene file's folder or inside one of the folders the user
//! allowed ([`ReadPolicy::new`]; the CLI's `--allow-read DIR`, the plugin's
//! `LightbakeConfig::allow_read`). Everything else is refused with a message naming the URI:
//! other schemes (`file:`, `http:`), absolute paths, `..` steps or links that lead out,
//! directories, devices and FIFOs (opened without blocking, so a FIFO cannot hang the
//! bake). A file larger than the caller's limit is refused before it is read.
//!
//! The rule is the same for every reader of scene files in lightbake: the importer, the
//! baked-glTF writer (which copies only bytes the importer read) and the split bake's shards.

use std::io::Read;
use std::path::{Component, Path, PathBuf};

use crate::error::{BakeError, Result};

/// The folders a scene's URIs may read from: the scene file's own, plus any the user allowed
/// (all with links resolved).
#[derive(Clone, Debug)]
pub struct ReadPolicy {
    /// The scene file's folder, as given (URIs are joined to it).
    base: PathBuf,
    /// Canonical folders a resolved file may lie in; the first is the scene's.
    roots: Vec<PathBuf>,
}

/// Where a URI's bytes come from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UriSource {
    /// An embedded `data:` URI's bytes, decoded.
    Data(Vec<u8>),
    /// A file inside an allowed folder, canonical.
    File(PathBuf),
}

impl ReadPolicy {
    /// The policy for the scene file `scene`, also allowing the folders `allow`.
    ///
    /// # Errors
    /// [`BakeError::Read`] when the scene's folder or an allowed folder does not exist.
    pub fn new(scene: &Path, allow: &[PathBuf]) -> Result<Self> {
        let base = match scene.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let canonical = |dir: &Path| {
            dir.canonicalize().map_err(|source| BakeError::Read {
                path: dir.to_path_buf(),
                source,
            })
        };
        let mut roots = vec![canonical(&base)?];
        for dir in allow {
            let c = canonical(dir)?;
            if !c.is_dir() {
                return Err(BakeError::Read {
                    path: dir.clone(),
                    source: std::io::Error::new(
                        std::io::ErrorKind::NotADirectory,
                        "an allowed read folder must be a folder",
                    ),
                });
            }
            roots.push(c);
        }
        Ok(Self { base, roots })
    }

    /// Where `uri` points, checked against the rule (the file is not opened).
    ///
    /// # Errors
    /// Why the URI is refused, as a phrase (the caller names the URI and its owner).
    pub fn locate(&self, uri: &str) -> std::result::Result<UriSource, String> {
        if let Some(rest) = uri.strip_prefix("data:") {
            return decode_data_uri(rest).map(UriSource::Data);
        }
        if let Some(scheme) = uri_scheme(uri) {
            return Err(format!(
                "a '{scheme}:' URI is not read: only paths relative to the scene's folder are"
            ));
        }
        let decoded = percent_decode(uri)?;
        let relative = Path::new(&decoded);
        if decoded.is_empty() {
            return Err("the URI is empty".into());
        }
        if relative.is_absolute() || decoded.starts_with('\\') || relative.has_root() {
            return Err(
                "an absolute path is not read: only paths relative to the scene's folder are"
                    .into(),
            );
        }
        if relative
            .components()
            .any(|c| matches!(c, Component::Prefix(_)))
        {
            return Err("a drive or device prefix is not read".into());
        }
        let joined = self.base.join(remove_dot_segments(&decoded));
        let canonical = joined
            .canonicalize()
            .map_err(|e| format!("cannot be found ({e})"))?;
        if !self.roots.iter().any(|r| canonical.starts_with(r)) {
            return Err(format!(
                "it leads to {}, outside the scene's folder{} (name further folders with --allow-read)",
                canonical.display(),
                if self.roots.len() > 1 {
                    " and the allowed folders"
                } else {
                    ""
                }
            ));
        }
        Ok(UriSource::File(canonical))
    }

    /// The bytes `uri` names, at most `limit` of them (a longer file is refused).
    ///
    /// # Errors
    /// Why the URI is refused or cannot be read, as a phrase.
    pub fn read(&self, uri: &str, limit: u64) -> std::result::Result<(UriSource, Vec<u8>), String> {
        self.read_with(uri, limit, false)
    }

    /// The first `count` bytes `uri` names (a buffer's declared length: a longer file's tail
    /// is never read).
    ///
    /// # Errors
    /// Why the URI is refused or cannot be read, as a phrase.
    pub fn read_prefix(
        &self,
        uri: &str,
        count: u64,
    ) -> std::result::Result<(UriSource, Vec<u8>), String> {
        self.read_with(uri, count, true)
    }

    fn read_with(
        &self,
        uri: &str,
        limit: u64,
        prefix: bool,
    ) -> std::result::Result<(UriSource, Vec<u8>), String> {
        match self.locate(uri)? {
            UriSource::Data(mut bytes) => {
                if bytes.len() as u64 > limit {
                    if !prefix {
                        return Err(too_large(bytes.len() as u64, limit));
                    }
                    bytes.truncate(limit as usize);
                }
                Ok((UriSource::Data(Vec::new()), bytes))
            }
            UriSource::File(path) => {
                let (file, meta) = open_regular_file(&path)?;
                if meta.len() > limit && !prefix {
                    return Err(too_large(meta.len(), limit));
                }
                let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
                file.take(limit)
                    .read_to_end(&mut bytes)
                    .map_err(|e| format!("cannot be read ({e})"))?;
                Ok((UriSource::File(path), bytes))
            }
        }
    }
}

fn too_large(size: u64, limit: u64) -> String {
    format!(
        "it holds {size} bytes, more than the {limit} the import may read (the memory budget; --memory-budget)"
    )
}

/// Reads a regular file of at most `limit` bytes: opened without following a final link and
/// without blocking (a FIFO), then checked to be a regular file before anything is read.
///
/// # Errors
/// Why it cannot be read, as a phrase.
pub fn read_regular_file(path: &Path, limit: u64) -> std::result::Result<Vec<u8>, String> {
    let (file, meta) = open_regular_file(path)?;
    if meta.len() > limit {
        return Err(too_large(meta.len(), limit));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot be read ({e})"))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64, limit));
    }
    Ok(bytes)
}

/// Opens a regular file for reading without blocking (a FIFO would wait for a writer) and
/// without following a final link, and checks what it opened.
///
/// # Errors
/// Why it cannot be opened, or what it is instead of a regular file, as a phrase.
pub fn open_regular_file(
    path: &Path,
) -> std::result::Result<(std::fs::File, std::fs::Metadata), String> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW);
    }
    let file = options
        .open(path)
        .map_err(|e| format!("cannot be opened ({e})"))?;
    let meta = file
        .metadata()
        .map_err(|e| format!("cannot be read ({e})"))?;
    if !meta.is_file() {
        let kind = file_kind(&meta);
        return Err(format!("it is {kind}, not a regular file"));
    }
    Ok((file, meta))
}

/// "a directory", "a FIFO", …
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    if meta.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// A relative path with its `.` segments dropped and each `..` taking the segment before it
/// away (RFC 3986 §5.2.4), so `a/../b.bin` names `b.bin` whether or not `a` exists; leading
/// `..` segments stay (the folder check decides where they lead).
fn remove_dot_segments(path: &str) -> PathBuf {
    let mut out: Vec<&str> = Vec::new();
    for seg in path.split('/') {
        match seg {
            "" | "." => {}
            ".." if out.last().is_some_and(|s| *s != "..") => {
                out.pop();
            }
            s => out.push(s),
        }
    }
    out.iter().collect()
}

/// The scheme of an absolute URI (`file`, `http`), if it has one (RFC 3986 §3.1: a letter,
/// then letters, digits, `+`, `-`, `.`, before the first `:`, with no `/` before it).
fn uri_scheme(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let scheme = &uri[..colon];
    let mut chars = scheme.chars();
    let first = chars.next()?;
    (first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(scheme)
}

/// Percent-decodes a URI path (RFC 3986 §2.1).
///
/// # Errors
/// A malformed escape, a result that is not UTF-8, or a NUL byte.
pub fn percent_decode(uri: &str) -> std::result::Result<String, String> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| {
                    format!("'%' at byte {i} does not start an escape of two hex digits")
                })?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    if out.contains(&0) {
        return Err("it holds a NUL byte".into());
    }
    String::from_utf8(out).map_err(|_| "its percent escapes do not decode to UTF-8".into())
}

/// A relative path written as a URI: every byte outside RFC 3986's unreserved set and `/` is
/// percent-encoded (`a%41.bin` → `a%2541.bin`, a space → `%20`), so any file name survives a
/// reader that decodes it.
pub fn percent_encode_path(path: &str) -> String {
    let mut out = String::with_capacity(path.len());
    for &b in path.as_bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~' | b'/') {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// The bytes of a `data:` URI's part after `data:` (`[mime][;param]*;base64,DATA`).
///
/// # Errors
/// Not base64, or without a comma.
fn decode_data_uri(rest: &str) -> std::result::Result<Vec<u8>, String> {
    use base64::Engine;
    let (meta, data) = rest.split_once(',').ok_or("a data: URI without a comma")?;
    if !meta.ends_with(";base64") {
        return Err("a data: URI that is not base64".into());
    }
    base64::engine::general_purpose::STANDARD
        .decode(data.trim_end())
        .map_err(|e| format!("a data: URI whose base64 does not decode ({e})"))
}

/// The `bufferView` indices a glTF document uses anywhere (accessors, their sparse parts,
/// images, extensions): every integer under a `bufferView` key.
pub fn used_buffer_views(json: &serde_json::Value) -> Vec<bool> {
    let count = json
        .get("bufferViews")
        .and_then(serde_json::Value::as_array)
        .map_or(0, Vec::len);
    let mut used = vec![false; count];
    let mut stack = vec![json];
    while let Some(v) = stack.pop() {
        match v {
            serde_json::Value::Object(map) => {
                for (k, child) in map {
                    if k == "bufferView"
                        && let Some(i) = child.as_u64()
                        && let Some(u) = used.get_mut(i as usize)
                    {
                        *u = true;
                    }
                    stack.push(child);
                }
            }
            serde_json::Value::Array(list) => stack.extend(list),
            _ => {}
        }
    }
    used
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode_strictly_and_encode_back() {
        assert_eq!(percent_decode("my%20scene.bin").unwrap(), "my scene.bin");
        assert_eq!(percent_decode("%2e%2E/x").unwrap(), "../x");
        assert!(percent_decode("a%FF.bin").is_err());
        assert!(percent_decode("a%4").is_err());
        assert!(percent_decode("a%zz").is_err());
        assert!(percent_decode("a%00b").is_err());
        for name in ["a%41.bin", "%FF #1?.bin", "dir/ä b.png", "x"] {
            assert_eq!(percent_decode(&percent_encode_path(name)).unwrap(), name);
        }
        assert_eq!(percent_encode_path("a b/c%.bin"), "a%20b/c%25.bin");
    }

    #[test]
    fn schemes_are_told_from_relative_paths() {
        assert_eq!(uri_scheme("file:///etc/passwd"), Some("file"));
        assert_eq!(uri_scheme("http://x"), Some("http"));
        assert_eq!(uri_scheme("c:/x"), Some("c"));
        assert_eq!(uri_scheme("a/b:c.bin"), None);
        assert_eq!(uri_scheme("scene.bin"), None);
        assert_eq!(uri_scheme("1a:b"), None);
    }

    #[test]
    fn reads_stay_inside_the_allowed_folders() {
        let dir = tempfile::tempdir().unwrap();
        let scene_dir = dir.path().join("scene");
        let shared = dir.path().join("shared");
        std::fs::create_dir_all(scene_dir.join("sub")).unwrap();
        std::fs::create_dir_all(&shared).unwrap();
        std::fs::write(scene_dir.join("a b.bin"), b"inside").unwrap();
        std::fs::write(shared.join("s.png"), b"shared").unwrap();
        let scene = scene_dir.join("scene.gltf");
        let policy = ReadPolicy::new(&scene, &[]).unwrap();
        let read = |p: &ReadPolicy, uri: &str| p.read(uri, 1 << 20).map(|(_, b)| b);
        assert_eq!(read(&policy, "a%20b.bin").unwrap(), b"inside");
        assert_eq!(read(&policy, "sub/../a%20b.bin").unwrap(), b"inside");
        assert!(
            read(&policy, "../shared/s.png")
                .unwrap_err()
                .contains("outside")
        );
        assert!(
            read(&policy, "%2e%2e/shared/s.png")
                .unwrap_err()
                .contains("outside")
        );
        let abs = shared.join("s.png").to_string_lossy().into_owned();
        assert!(read(&policy, &abs).unwrap_err().contains("absolute"));
        assert!(
            read(&policy, &format!("file://{abs}"))
                .unwrap_err()
                .contains("file:")
        );
        assert!(read(&policy, "sub").unwrap_err().contains("directory"));
        assert!(read(&policy, "a%20b.bin").is_ok());
        assert!(
            policy
                .read("a%20b.bin", 3)
                .unwrap_err()
                .contains("more than")
        );
        assert_eq!(
            read(&policy, "data:application/octet-stream;base64,aGk=").unwrap(),
            b"hi"
        );
        assert!(read(&policy, "data:text/plain,hi").is_err());
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(shared.join("s.png"), scene_dir.join("link.png")).unwrap();
            std::os::unix::fs::symlink("/dev/zero", scene_dir.join("zero.bin")).unwrap();
            assert!(read(&policy, "link.png").unwrap_err().contains("outside"));
            assert!(read(&policy, "zero.bin").unwrap_err().contains("outside"));
        }
        let allowed = ReadPolicy::new(&scene, std::slice::from_ref(&shared)).unwrap();
        assert_eq!(read(&allowed, "../shared/s.png").unwrap(), b"shared");
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe.bin");
        assert!(
            std::process::Command::new("mkfifo")
                .arg(&fifo)
                .status()
                .unwrap()
                .success()
        );
        let policy = ReadPolicy::new(&dir.path().join("s.gltf"), &[]).unwrap();
        assert!(policy.read("pipe.bin", 100).unwrap_err().contains("FIFO"));
    }

    #[test]
    fn used_views_are_found_anywhere() {
        let json = serde_json::json!({
            "bufferViews": [{}, {}, {}, {}],
            "accessors": [{ "bufferView": 0, "sparse": { "indices": { "bufferView": 2 } } }],
            "images": [{ "bufferView": 3 }],
        });
        assert_eq!(used_buffer_views(&json), vec![true, false, true, true]);
    }
}
