//! The on-disk cache of references, error curves, per-configuration results and figure
//! images.
//!
//! # Keys
//! A [`CacheKey`] is a kind plus an ordered list of `name=value` fields naming everything
//! the entry depends on (scene fingerprint, frame, eye, resolution, spp, seeds, the code
//! version, ...). Its canonical text is stored inside the entry and compared on read, so a
//! hash collision is a miss, never a wrong hit. The file is
//! `<root>/<kind>/<scene>/<fnv64 of the text>.bin`.
//!
//! # Entries
//! ```text
//! magic "STEVCACH" | u32 format | u32 key length | key text | u64 payload length |
//! u64 checksum (FNV-1a over 64-bit little-endian words of key text + payload) | payload
//! ```
//! All integers little-endian. The checksum detects truncation and bit rot, not tampering.
//! A read that finds a bad magic, another format, another key, a wrong length or a wrong
//! checksum reports [`Lookup::Corrupt`]; the caller recomputes and overwrites the entry.
//!
//! # Atomic writes
//! An entry is written to a temporary file in the same folder (`.tmp-<pid>-<n>`), flushed
//! to disk, then renamed over the final name. A reader sees the old entry or the new one,
//! never half of one; a write that fails (or a process killed mid-write) leaves at most a
//! stray temporary file, which [`Cache::open`] removes from earlier runs.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::curve::{CurvePoint, SampleSums};
use crate::kernels::{Extent, PlaneBuf, RgbBuf};

/// Bumped whenever the meaning or layout of any entry changes.
pub const CACHE_FORMAT: u32 = 2;

const MAGIC: &[u8; 8] = b"STEVCACH";

/// Age after which another process's temporary file counts as abandoned.
pub const STALE_TEMP: std::time::Duration = std::time::Duration::from_secs(600);

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// FNV-1a over 64-bit little-endian words (the tail zero-padded), then the length.
pub fn checksum(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut len = 0u64;
    for part in parts {
        let mut chunks = part.chunks_exact(8);
        for c in &mut chunks {
            h = (h ^ u64::from_le_bytes(c.try_into().expect("8 bytes"))).wrapping_mul(0x0000_0100_0000_01b3);
        }
        let rest = chunks.remainder();
        if !rest.is_empty() {
            let mut b = [0u8; 8];
            b[..rest.len()].copy_from_slice(rest);
            h = (h ^ u64::from_le_bytes(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        len += part.len() as u64;
    }
    (h ^ len).wrapping_mul(0x0000_0100_0000_01b3)
}

/// What an entry depends on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CacheKey {
    kind: &'static str,
    scene: String,
    text: String,
}

impl CacheKey {
    /// A key of `kind` for `scene` (used for the folder) with the fields in order.
    pub fn new(kind: &'static str, scene: &str, fields: &[(&str, String)]) -> Self {
        let mut text = format!("{kind};format={CACHE_FORMAT};scene={scene}");
        for (name, value) in fields {
            text.push(';');
            text.push_str(name);
            text.push('=');
            text.push_str(value);
        }
        Self { kind, scene: scene.to_owned(), text }
    }

    /// A key extending this one by more fields (a new kind).
    pub fn derive(&self, kind: &'static str, fields: &[(&str, String)]) -> Self {
        let mut k = Self::new(kind, &self.scene, fields);
        k.text.push_str(";of=");
        k.text.push_str(&self.text);
        k
    }

    /// The canonical text (kind, format, scene, then the fields), stored in the entry and
    /// compared on read.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// The kind (`reference`, `curve`, `config`, ...): the entry's top-level folder.
    pub fn kind(&self) -> &'static str {
        self.kind
    }

    /// A 64-bit hash of the text (the file name).
    pub fn hash(&self) -> u64 {
        checksum(&[self.text.as_bytes()])
    }
}

/// The result of a read.
#[derive(Debug, PartialEq)]
pub enum Lookup {
    /// The entry verified; its payload.
    Hit(Vec<u8>),
    /// No entry file.
    Miss,
    /// The file exists but failed verification; the reason names what was wrong.
    Corrupt(String),
}

/// A cache folder.
#[derive(Clone, Debug)]
pub struct Cache {
    root: PathBuf,
}

fn io_err(path: &Path, what: &str, e: io::Error) -> String {
    format!("{}: cannot {what}: {e}", path.display())
}

impl Cache {
    /// Opens (creating) the cache at `root` and removes temporary files that earlier runs
    /// left behind: those of other processes untouched for [`STALE_TEMP`] (a live writer
    /// renames its file within seconds, so a concurrent run's writes are safe).
    pub fn open(root: &Path) -> Result<Self, String> {
        fs::create_dir_all(root).map_err(|e| io_err(root, "create the cache folder", e))?;
        let cache = Self { root: root.to_path_buf() };
        cache.remove_stale_temps();
        Ok(cache)
    }

    /// The cache folder, under which every entry's path lies.
    pub fn root(&self) -> &Path {
        &self.root
    }

    fn remove_stale_temps(&self) {
        let own = format!(".tmp-{}-", std::process::id());
        let mut stack = vec![self.root.clone()];
        while let Some(dir) = stack.pop() {
            let Ok(entries) = fs::read_dir(&dir) else { continue };
            for entry in entries.flatten() {
                let path = entry.path();
                if path.is_dir() {
                    stack.push(path);
                } else if let Some(name) = path.file_name().and_then(|n| n.to_str())
                    && name.contains(".tmp-")
                    && !name.contains(&own)
                    && entry
                        .metadata()
                        .and_then(|m| m.modified())
                        .is_ok_and(|t| t.elapsed().is_ok_and(|a| a > STALE_TEMP))
                {
                    fs::remove_file(&path).ok();
                }
            }
        }
    }

    /// The file of `key`.
    pub fn path(&self, key: &CacheKey) -> PathBuf {
        let scene: String = key
            .scene
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
            .collect();
        self.root.join(key.kind).join(scene).join(format!("{:016x}.bin", key.hash()))
    }

    /// Whether an entry file exists (not verified).
    pub fn contains(&self, key: &CacheKey) -> bool {
        self.path(key).is_file()
    }

    /// Reads and verifies the entry of `key`.
    pub fn get(&self, key: &CacheKey) -> Lookup {
        let path = self.path(key);
        let bytes = match fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Lookup::Miss,
            Err(e) => return Lookup::Corrupt(io_err(&path, "read", e)),
        };
        match decode_entry(&bytes, key.text()) {
            Ok(payload) => Lookup::Hit(payload.to_vec()),
            Err(why) => Lookup::Corrupt(format!("{}: {why}", path.display())),
        }
    }

    /// Writes the entry of `key` atomically.
    pub fn put(&self, key: &CacheKey, payload: &[u8]) -> Result<(), String> {
        let text = key.text().as_bytes();
        let sum = checksum(&[text, payload]);
        write_atomic(&self.path(key), |w| {
            w.write_all(MAGIC)?;
            w.write_all(&CACHE_FORMAT.to_le_bytes())?;
            w.write_all(&(text.len() as u32).to_le_bytes())?;
            w.write_all(text)?;
            w.write_all(&(payload.len() as u64).to_le_bytes())?;
            w.write_all(&sum.to_le_bytes())?;
            w.write_all(payload)
        })
    }

    /// Removes the entry of `key` (if any).
    pub fn remove(&self, key: &CacheKey) {
        fs::remove_file(self.path(key)).ok();
    }
}

/// Checks an entry's framing and returns its payload.
pub(crate) fn decode_entry<'a>(bytes: &'a [u8], key_text: &str) -> Result<&'a [u8], String> {
    let mut r = Reader { bytes, pos: 0 };
    if r.take(8)? != MAGIC {
        return Err("not a cache entry (bad magic)".into());
    }
    let format = r.u32()?;
    if format != CACHE_FORMAT {
        return Err(format!("cache format {format}, expected {CACHE_FORMAT}"));
    }
    let key_len = r.u32()? as usize;
    let text = r.take(key_len)?;
    if text != key_text.as_bytes() {
        return Err("the entry belongs to another key (hash collision)".into());
    }
    let len = r.u64()? as usize;
    let sum = r.u64()?;
    let payload = r.take(len)?;
    if r.pos != bytes.len() {
        return Err(format!("{} trailing bytes", bytes.len() - r.pos));
    }
    if checksum(&[text, payload]) != sum {
        return Err("checksum mismatch".into());
    }
    Ok(payload)
}

/// Writes `path` through a temporary file in the same folder and a rename. On any error
/// the temporary file is removed and `path` is untouched.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut io::BufWriter<fs::File>) -> io::Result<()>,
) -> Result<(), String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    fs::create_dir_all(dir).map_err(|e| io_err(dir, "create folder", e))?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("entry");
    let tmp = dir.join(format!("{name}.tmp-{}-{}", std::process::id(), TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)));
    let result = (|| {
        let file = fs::File::create(&tmp)?;
        let mut w = io::BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        fs::rename(&tmp, path)
    })();
    result.map_err(|e| {
        fs::remove_file(&tmp).ok();
        io_err(path, "write", e)
    })
}

/// A cursor over bytes with bounds-checked reads.
pub struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    /// A reader at the first byte of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    /// The next `n` bytes; an error if fewer are left.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or("truncated entry")?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    /// The next 4 bytes as a little-endian `u32`.
    pub fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    /// The next 8 bytes as a little-endian `u64`.
    pub fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }

    /// The next `n` little-endian `f32` values.
    pub fn f32s(&mut self, n: usize) -> Result<Vec<f32>, String> {
        let bytes = self.take(n.checked_mul(4).ok_or("truncated entry")?)?;
        Ok(bytes.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes"))).collect())
    }

    /// The next `n` little-endian `f64` values.
    pub fn f64s(&mut self, n: usize) -> Result<Vec<f64>, String> {
        let bytes = self.take(n.checked_mul(8).ok_or("truncated entry")?)?;
        Ok(bytes.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect())
    }

    /// Whether every byte has been read (decoders refuse trailing bytes).
    pub fn finished(&self) -> bool {
        self.pos == self.bytes.len()
    }
}

/// Appends `width`, `height` and the three planes (f32, little-endian).
pub fn encode_image(img: &RgbBuf, out: &mut Vec<u8>) {
    let e = img.extent();
    out.extend_from_slice(&(e.width() as u32).to_le_bytes());
    out.extend_from_slice(&(e.height() as u32).to_le_bytes());
    for p in img.planes() {
        for v in p.as_slice() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// Reads what [`encode_image`] wrote.
pub fn decode_image(r: &mut Reader<'_>) -> Result<RgbBuf, String> {
    let (w, h) = (r.u32()? as usize, r.u32()? as usize);
    let e = Extent::new(w, h).map_err(|e| e.to_string())?;
    let mut plane =
        || -> Result<PlaneBuf, String> { PlaneBuf::from_vec(r.f32s(e.pixels())?, e).map_err(|e| e.to_string()) };
    let (r, g, b) = (plane()?, plane()?, plane()?);
    RgbBuf::from_planes(r, g, b).map_err(|e| e.to_string())
}

/// Appends `width`, `height` and the f64 sample sums (little-endian).
pub fn encode_sums(sums: &SampleSums, out: &mut Vec<u8>) {
    out.extend_from_slice(&(sums.extent.width() as u32).to_le_bytes());
    out.extend_from_slice(&(sums.extent.height() as u32).to_le_bytes());
    for v in &sums.rgb {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Reads what [`encode_sums`] wrote.
pub fn decode_sums(r: &mut Reader<'_>) -> Result<SampleSums, String> {
    let (w, h) = (r.u32()? as usize, r.u32()? as usize);
    let extent = Extent::new(w, h).map_err(|e| e.to_string())?;
    Ok(SampleSums { extent, rgb: r.f64s(3 * extent.pixels())? })
}

/// Appends `width`, `height` and the bytes of a byte plane.
pub fn encode_mask(m: &PlaneBuf<u8>, out: &mut Vec<u8>) {
    let e = m.extent();
    out.extend_from_slice(&(e.width() as u32).to_le_bytes());
    out.extend_from_slice(&(e.height() as u32).to_le_bytes());
    out.extend_from_slice(m.as_slice());
}

/// Reads what [`encode_mask`] wrote.
pub fn decode_mask(r: &mut Reader<'_>) -> Result<PlaneBuf<u8>, String> {
    let (w, h) = (r.u32()? as usize, r.u32()? as usize);
    let e = Extent::new(w, h).map_err(|e| e.to_string())?;
    PlaneBuf::from_vec(r.take(e.pixels())?.to_vec(), e).map_err(|e| e.to_string())
}

/// The payload of a checkpoint: the samples so far, the curve points so far, the sum.
pub(crate) fn encode_partial(samples: u32, points: &[CurvePoint], sum: &SampleSums) -> Vec<u8> {
    let json = serde_json::to_vec(points).expect("points serialise");
    let mut out = Vec::with_capacity(16 + json.len() + 24 * sum.extent.pixels());
    out.extend_from_slice(&samples.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    encode_sums(sum, &mut out);
    out
}

/// Reads back what [`encode_partial`] wrote; refuses anything else.
pub(crate) fn decode_partial(bytes: &[u8]) -> Result<(u32, Vec<CurvePoint>, SampleSums), String> {
    let mut r = Reader::new(bytes);
    let samples = r.u32()?;
    let len = r.u32()? as usize;
    let points = serde_json::from_slice(r.take(len)?).map_err(|e| e.to_string())?;
    let sum = decode_sums(&mut r)?;
    if !r.finished() {
        return Err("trailing bytes".into());
    }
    Ok((samples, points, sum))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("stereotrace-cache-{tag}-{}", std::process::id()));
        fs::remove_dir_all(&d).ok();
        d
    }

    #[test]
    fn entries_round_trip_and_keys_are_checked() {
        let dir = temp_dir("rt");
        let cache = Cache::open(&dir).unwrap();
        let key = CacheKey::new("curve", "atrium", &[("frame", "3".into())]);
        assert_eq!(cache.get(&key), Lookup::Miss);
        cache.put(&key, b"hello").unwrap();
        assert_eq!(cache.get(&key), Lookup::Hit(b"hello".to_vec()));
        // Another key whose file name we force to collide is refused by the key text check.
        let other = CacheKey::new("curve", "atrium", &[("frame", "4".into())]);
        fs::copy(cache.path(&key), cache.path(&other)).unwrap();
        assert!(matches!(cache.get(&other), Lookup::Corrupt(m) if m.contains("another key")));
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn every_flipped_byte_and_truncation_is_detected() {
        let dir = temp_dir("flip");
        let cache = Cache::open(&dir).unwrap();
        let key = CacheKey::new("reference", "cornell", &[("spp", "4".into())]);
        cache.put(&key, &(0..=255u8).collect::<Vec<_>>()).unwrap();
        let path = cache.path(&key);
        let good = fs::read(&path).unwrap();
        for i in 0..good.len() {
            let mut bad = good.clone();
            bad[i] ^= 0x10;
            fs::write(&path, &bad).unwrap();
            assert!(matches!(cache.get(&key), Lookup::Corrupt(_)), "flip at byte {i} went unnoticed");
        }
        for n in [0, 7, good.len() / 2, good.len() - 1] {
            fs::write(&path, &good[..n]).unwrap();
            assert!(matches!(cache.get(&key), Lookup::Corrupt(_)), "truncation to {n} went unnoticed");
        }
        fs::write(&path, &good).unwrap();
        assert!(matches!(cache.get(&key), Lookup::Hit(_)));
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_failed_write_leaves_the_old_entry_and_no_temporary_file() {
        let dir = temp_dir("atomic");
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("entry.bin");
        write_atomic(&path, |w| w.write_all(b"old")).unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"partial new content")?;
            Err(io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.contains("disk full") && err.contains("entry.bin"), "{err}");
        assert_eq!(fs::read(&path).unwrap(), b"old");
        let names: Vec<_> = fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("entry.bin")]);
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn stale_temporary_files_are_removed_on_open() {
        let dir = temp_dir("stale");
        let sub = dir.join("curve/atrium");
        fs::create_dir_all(&sub).unwrap();
        fs::write(sub.join("0123.bin.tmp-999999999-0"), b"junk").unwrap();
        fs::write(sub.join("0456.bin.tmp-999999999-1"), b"a concurrent writer").unwrap();
        fs::write(sub.join("0123.bin"), b"kept").unwrap();
        let old = std::time::SystemTime::now() - 2 * STALE_TEMP;
        fs::File::options().write(true).open(sub.join("0123.bin.tmp-999999999-0")).unwrap().set_modified(old).unwrap();
        Cache::open(&dir).unwrap();
        assert!(!sub.join("0123.bin.tmp-999999999-0").exists());
        assert!(sub.join("0456.bin.tmp-999999999-1").exists(), "a fresh temporary file may be a live writer's");
        assert!(sub.join("0123.bin").exists());
        fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn images_and_masks_round_trip() {
        let e = Extent::new(3, 2).unwrap();
        let mut img = RgbBuf::new(e, 0.5);
        img.set(2, 1, [1e6, -0.0, f32::MIN_POSITIVE]);
        let mut bytes = Vec::new();
        encode_image(&img, &mut bytes);
        let mut m = PlaneBuf::new(e, 3u8);
        m.as_mut_slice()[4] = 1;
        encode_mask(&m, &mut bytes);
        let mut r = Reader::new(&bytes);
        assert_eq!(decode_image(&mut r).unwrap(), img);
        assert_eq!(decode_mask(&mut r).unwrap(), m);
        assert!(r.finished());
    }
}
