//! Split renders: a render's samples in `N` disjoint shares, each rendered
//! anywhere (another process, another machine, a cluster's array job) and
//! kept as a *partial* (the exact per-pixel sums, not a rounded image),
//! then merged into the very bytes one process makes.
//!
//! Share `K` of `N` takes the sample indices
//! `spp * (K - 1) / N .. spp * K / N` of every pixel ([`Share::samples`]),
//! so each costs about `1/N` of the render. Every sample comes from the
//! stream keyed by (seed, pixel, sample index) whoever renders it, and the
//! film's sums are exact ([`ExactRgb`]), so adding the
//! shares' sums in any order gives exactly the film of one render.
//!
//! The partial file format (version 1), all integers little-endian:
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `LUCPART\n` |
//! | 4 | format version, u32 (1) |
//! | 4 | header length `H`, u32 (at most 64 KiB) |
//! | `H` | header: UTF-8 lines `key: value` (scene, scene_hash, settings, size, spp, share) |
//! | `52 * width * height` | per pixel, row-major from the top: three i128 channel sums in units of 2^-64, then the u32 count of non-finite samples |
//! | 8 | checksum, u64, of everything before it |
//!
//! [`read_partial`] checks the magic, the version, the header, the length
//! and the checksum, so a truncated or corrupted file is an error, never a
//! wrong image. [`Merger`] checks that parts belong together (same scene
//! hash, settings, size and spp) and cover every share exactly once, naming
//! the part at fault.
//!
//! ```
//! use lucent_render::{extract, render, RenderSettings, partial::{self, Merger, PartialHeader, Share}};
//! use lucent_scene::{Scene, components::{Camera, OrbitRig}};
//! let mut scene = Scene::default();
//! scene.add_camera("cam", Camera::default(), OrbitRig::default());
//! let rs = extract(&scene)?;
//! let settings = RenderSettings { width: 8, height: 4, spp: 5, ..RenderSettings::default() };
//! let mut merger = Merger::new();
//! for k in [2, 1] {
//!     let share = Share::new(k, 2).ok_or("bad share")?;
//!     let part = partial::render_share(&rs, &settings, share, &|_| {});
//!     let header = PartialHeader::new("demo", 7, "demo settings", &settings, share);
//!     let mut bytes = Vec::new();
//!     partial::write_partial(&mut bytes, &header, &part.film)?;
//!     merger.add(&format!("part{k}"), &mut bytes.as_slice())?;
//! }
//! let (_, film) = merger.finish()?;
//! assert_eq!(film, render(&rs, &settings, &|_| {}).film);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::{ExactRgb, Film, RenderOutput, RenderScene, RenderSettings, render_samples};
use std::fmt;
use std::io::{self, Read, Write};
use std::ops::Range;
use std::time::Instant;

/// The file's first bytes.
pub const MAGIC: &[u8; 8] = b"LUCPART\n";

/// The format version this code writes and reads.
pub const VERSION: u32 = 1;

/// Bytes per pixel in the body.
const PIXEL_BYTES: usize = 52;

/// The longest header accepted.
const MAX_HEADER: u32 = 64 * 1024;

/// Pixels read or written per buffered block.
const BLOCK: usize = 4096;

/// Share `index` (1-based) of `count` disjoint shares of a render's
/// samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Share {
    index: u32,
    count: u32,
}

impl Share {
    /// Share `index` of `count`; `None` unless `1 <= index <= count`.
    pub fn new(index: u32, count: u32) -> Option<Share> {
        (index >= 1 && index <= count).then_some(Share { index, count })
    }

    /// Parses `K/N`.
    pub fn parse(s: &str) -> Result<Share, String> {
        let bad = || format!("'{s}' is not a share K/N with 1 <= K <= N, e.g. 2/8");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        Share::new(k, n).ok_or_else(bad)
    }

    /// K, from 1.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// N.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The sample indices of this share of `spp` samples per pixel: a
    /// contiguous range, the shares in order tiling `0..spp`, their sizes
    /// differing by at most one (empty when `count > spp`).
    pub fn samples(&self, spp: u32) -> Range<u32> {
        let at = |k: u32| (u64::from(spp) * u64::from(k) / u64::from(self.count)) as u32;
        at(self.index - 1)..at(self.index)
    }
}

impl fmt::Display for Share {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Renders share `share` of `settings.spp` samples per pixel: a film
/// holding only those samples (its `n_samples` is the share's size).
/// `progress` is called with rows finished, as in [`render`](crate::render).
pub fn render_share(
    scene: &RenderScene,
    settings: &RenderSettings,
    share: Share,
    progress: &(dyn Fn(usize) + Sync),
) -> RenderOutput {
    let mut film = Film::new(settings.width.max(1), settings.height.max(1));
    let start = Instant::now();
    let stats = render_samples(scene, settings, &mut film, share.samples(settings.spp.max(1)), progress);
    RenderOutput {
        film,
        stats,
        elapsed: start.elapsed(),
    }
}

/// What a partial file says about itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartialHeader {
    /// The scene as the renderer named it (informative only).
    pub scene: String,
    /// A hash of the scene's content (the scene file and every file it
    /// loads): parts must agree on it.
    pub scene_hash: u64,
    /// Every setting that changes the image, as text: parts must agree on
    /// it.
    pub settings: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// Which share of the samples the file holds.
    pub share: Share,
}

impl PartialHeader {
    /// The header of `share` of a render with `settings` (size and spp are
    /// taken from it; `settings_text` must describe everything else that
    /// changes the image).
    pub fn new(scene: &str, scene_hash: u64, settings_text: &str, settings: &RenderSettings, share: Share) -> Self {
        Self {
            scene: scene.replace(['\n', '\r'], " "),
            scene_hash,
            settings: settings_text.replace(['\n', '\r'], " "),
            width: settings.width.max(1),
            height: settings.height.max(1),
            spp: settings.spp.max(1),
            share,
        }
    }

    fn to_text(&self) -> String {
        format!(
            "scene: {}\nscene_hash: {:016x}\nsettings: {}\nsize: {}x{}\nspp: {}\nshare: {}\n",
            self.scene, self.scene_hash, self.settings, self.width, self.height, self.spp, self.share
        )
    }

    fn parse(text: &str) -> Result<Self, PartialError> {
        let field = |key: &str| {
            text.lines()
                .find_map(|l| l.strip_prefix(key).and_then(|r| r.strip_prefix(": ")))
                .ok_or_else(|| PartialError::Header(format!("no '{key}' line")))
        };
        let bad = |key: &str, v: &str| PartialError::Header(format!("bad {key} '{v}'"));
        let hash = field("scene_hash")?;
        let size = field("size")?;
        let (w, h) = size.split_once('x').ok_or_else(|| bad("size", size))?;
        let dim = |v: &str| match v.parse::<u32>() {
            Ok(n) if (1..=65536).contains(&n) => Ok(n),
            _ => Err(bad("size", size)),
        };
        let spp = field("spp")?;
        let share = field("share")?;
        Ok(Self {
            scene: field("scene")?.to_owned(),
            scene_hash: u64::from_str_radix(hash, 16).map_err(|_| bad("scene_hash", hash))?,
            settings: field("settings")?.to_owned(),
            width: dim(w)?,
            height: dim(h)?,
            spp: match spp.parse::<u32>() {
                Ok(n) if n >= 1 => n,
                _ => return Err(bad("spp", spp)),
            },
            share: Share::parse(share).map_err(PartialError::Header)?,
        })
    }
}

/// Why a partial file could not be read.
#[derive(Debug)]
pub enum PartialError {
    /// Not a partial file.
    NotPartial,
    /// A version this code does not read.
    Version(u32),
    /// The header is missing a line or has a bad value.
    Header(String),
    /// The file ends early.
    Truncated {
        /// Bytes expected in all.
        expected: u64,
        /// Bytes there were.
        found: u64,
    },
    /// The checksum does not match the content.
    Corrupt,
    /// Bytes after the checksum.
    TrailingBytes,
    /// Reading failed.
    Io(io::Error),
}

impl fmt::Display for PartialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PartialError::NotPartial => write!(f, "not a Lucent partial file (no LUCPART magic)"),
            PartialError::Version(v) => write!(
                f,
                "partial file format version {v}; this lucent reads version {VERSION}"
            ),
            PartialError::Header(m) => write!(f, "bad partial file header: {m}"),
            PartialError::Truncated { expected, found } => write!(
                f,
                "truncated: {found} bytes where the header promises {expected} (a render killed while writing?)"
            ),
            PartialError::Corrupt => write!(f, "corrupted: the checksum does not match the content"),
            PartialError::TrailingBytes => write!(f, "corrupted: bytes after the end of the data"),
            PartialError::Io(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PartialError {}

/// The running checksum of a file's bytes (a 64-bit multiply-rotate hash of
/// 8-byte words; it detects corruption, it is no cryptographic seal).
#[derive(Clone, Copy)]
struct Checksum(u64);

impl Checksum {
    fn new() -> Self {
        Checksum(0xcbf2_9ce4_8422_2325)
    }

    fn add(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            let mut w = [0u8; 8];
            w.copy_from_slice(c);
            self.word(u64::from_le_bytes(w));
        }
        for &b in chunks.remainder() {
            self.word(u64::from(b) | 0x100);
        }
    }

    #[inline]
    fn word(&mut self, w: u64) {
        self.0 = (self.0.rotate_left(5) ^ w).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

/// Writes a partial file: `header` and the exact sums of `film` (which
/// must be `header`'s size and hold the share's samples).
pub fn write_partial(out: &mut impl Write, header: &PartialHeader, film: &Film) -> io::Result<()> {
    if (film.width(), film.height()) != (header.width, header.height) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the film's size is not the header's",
        ));
    }
    let text = header.to_text();
    let mut sum = Checksum::new();
    let mut put = |out: &mut dyn Write, bytes: &[u8]| -> io::Result<()> {
        sum.add(bytes);
        out.write_all(bytes)
    };
    put(out, MAGIC)?;
    put(out, &VERSION.to_le_bytes())?;
    put(out, &(text.len() as u32).to_le_bytes())?;
    put(out, text.as_bytes())?;
    let mut block = Vec::with_capacity(BLOCK * PIXEL_BYTES);
    for pixels in film.sums().chunks(BLOCK) {
        block.clear();
        for p in pixels {
            let (rgb, bad) = p.raw();
            for c in rgb {
                block.extend_from_slice(&c.to_le_bytes());
            }
            block.extend_from_slice(&bad.to_le_bytes());
        }
        put(out, &block)?;
    }
    out.write_all(&sum.0.to_le_bytes())
}

/// A reader that counts the bytes it has given.
struct Counted<'a, R: Read> {
    inner: &'a mut R,
    read: u64,
    sum: Checksum,
}

impl<R: Read> Counted<'_, R> {
    /// Fills `buf`, or says how far the file went.
    fn fill(&mut self, buf: &mut [u8], expected: u64) -> Result<(), PartialError> {
        let mut at = 0;
        while at < buf.len() {
            match self.inner.read(&mut buf[at..]) {
                Ok(0) => {
                    return Err(PartialError::Truncated {
                        expected,
                        found: self.read + at as u64,
                    });
                }
                Ok(n) => at += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(PartialError::Io(e)),
            }
        }
        self.read += buf.len() as u64;
        self.sum.add(buf);
        Ok(())
    }
}

/// Reads a partial file's header, then hands each block of pixel sums to
/// `pixels` (in order), then checks the checksum and the end of the file.
fn read_with(
    input: &mut impl Read,
    check_header: &mut dyn FnMut(&PartialHeader) -> Result<(), PartialError>,
    pixels: &mut dyn FnMut(usize, &[ExactRgb]),
) -> Result<PartialHeader, PartialError> {
    let mut r = Counted {
        inner: input,
        read: 0,
        sum: Checksum::new(),
    };
    let mut magic = [0u8; 8];
    let mut word = [0u8; 4];
    // Too short for the magic is "not a partial file" too.
    r.fill(&mut magic, 16).map_err(|_| PartialError::NotPartial)?;
    if &magic != MAGIC {
        return Err(PartialError::NotPartial);
    }
    r.fill(&mut word, 16)?;
    let version = u32::from_le_bytes(word);
    if version != VERSION {
        return Err(PartialError::Version(version));
    }
    r.fill(&mut word, 16)?;
    let len = u32::from_le_bytes(word);
    if len > MAX_HEADER {
        return Err(PartialError::Header(format!("{len} bytes long")));
    }
    let mut text = vec![0u8; len as usize];
    r.fill(&mut text, 16 + u64::from(len))?;
    let text = String::from_utf8(text).map_err(|_| PartialError::Header("not UTF-8".into()))?;
    let header = PartialHeader::parse(&text)?;
    check_header(&header)?;
    let n = header.width as usize * header.height as usize;
    let expected = 16 + u64::from(len) + (n * PIXEL_BYTES) as u64 + 8;
    let mut block = vec![0u8; BLOCK * PIXEL_BYTES];
    let mut sums = Vec::with_capacity(BLOCK);
    let mut at = 0;
    while at < n {
        let k = BLOCK.min(n - at);
        let bytes = &mut block[..k * PIXEL_BYTES];
        r.fill(bytes, expected)?;
        sums.clear();
        for p in bytes.chunks_exact(PIXEL_BYTES) {
            let mut c = [0i128; 3];
            for (i, c) in c.iter_mut().enumerate() {
                let mut b = [0u8; 16];
                b.copy_from_slice(&p[16 * i..16 * i + 16]);
                *c = i128::from_le_bytes(b);
            }
            let mut b = [0u8; 4];
            b.copy_from_slice(&p[48..52]);
            sums.push(ExactRgb::from_raw(c, u32::from_le_bytes(b)));
        }
        pixels(at, &sums);
        at += k;
    }
    let computed = r.sum.0;
    let mut stored = [0u8; 8];
    r.fill(&mut stored, expected)?;
    if u64::from_le_bytes(stored) != computed {
        return Err(PartialError::Corrupt);
    }
    let mut extra = [0u8; 1];
    loop {
        match r.inner.read(&mut extra) {
            Ok(0) => return Ok(header),
            Ok(_) => return Err(PartialError::TrailingBytes),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(PartialError::Io(e)),
        }
    }
}

/// Reads a whole partial file: its header and a film holding its share's
/// samples.
pub fn read_partial(input: &mut impl Read) -> Result<(PartialHeader, Film), PartialError> {
    let mut sums = Vec::new();
    let header = read_with(input, &mut |_| Ok(()), &mut |_, block| sums.extend_from_slice(block))?;
    let n = header.share.samples(header.spp).len() as u32;
    let film = Film::from_sums(header.width, header.height, n, sums)
        .ok_or_else(|| PartialError::Header("pixel count".into()))?;
    Ok((header, film))
}

/// Why parts do not merge.
#[derive(Debug)]
pub enum MergeError {
    /// A part could not be read.
    Read {
        /// The part's name.
        part: String,
        /// Why.
        error: PartialError,
    },
    /// A part does not belong with the first one.
    Mismatch {
        /// The part's name.
        part: String,
        /// The first part's name.
        first: String,
        /// What differs.
        what: String,
    },
    /// A share given twice.
    Duplicate {
        /// The part's name.
        part: String,
        /// The part that already had it.
        earlier: String,
        /// The share.
        share: Share,
    },
    /// Shares no part gave.
    Missing {
        /// Their indices (1-based).
        shares: Vec<u32>,
        /// N.
        count: u32,
    },
    /// No parts at all.
    Empty,
}

impl fmt::Display for MergeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MergeError::Read { part, error } => write!(f, "{part}: {error}"),
            MergeError::Mismatch { part, first, what } => {
                write!(f, "{part}: does not belong with {first}: {what}")
            }
            MergeError::Duplicate { part, earlier, share } => {
                write!(f, "{part}: share {share} again (already given by {earlier})")
            }
            MergeError::Missing { shares, count } => {
                let list: Vec<String> = shares.iter().map(|k| format!("{k}/{count}")).collect();
                write!(
                    f,
                    "missing share{} {} of {count}: no part holds {}",
                    if shares.len() == 1 { "" } else { "s" },
                    list.join(", "),
                    if shares.len() == 1 { "it" } else { "them" }
                )
            }
            MergeError::Empty => write!(f, "no parts to merge"),
        }
    }
}

impl std::error::Error for MergeError {}

/// The first difference between two settings texts, as `here` against
/// `there`.
fn first_difference(here: &str, there: &str) -> String {
    let split = |s: &str| -> Vec<String> {
        s.split([',', '{', '}'])
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(str::to_owned)
            .collect()
    };
    let (a, b) = (split(here), split(there));
    for i in 0..a.len().max(b.len()) {
        let (x, y) = (a.get(i), b.get(i));
        if x != y {
            let show = |t: Option<&String>| t.map_or_else(|| "nothing".to_owned(), |t| format!("'{t}'"));
            return format!("settings differ: {} here, {} there", show(x), show(y));
        }
    }
    "settings differ".to_owned()
}

/// Merges parts one at a time (reading each as a stream, so only one film
/// of sums is held), checking that they belong together and cover every
/// share once.
#[derive(Default)]
pub struct Merger {
    first: Option<(String, PartialHeader)>,
    film: Option<Film>,
    seen: Vec<Option<String>>,
}

impl Merger {
    /// No parts yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads the part named `name` from `input` and adds it.
    ///
    /// On an error the merger must not be used further (a corrupted part is
    /// only known to be corrupted at its end, after its sums were added).
    pub fn add(&mut self, name: &str, input: &mut impl Read) -> Result<(), MergeError> {
        let read_err = |error| MergeError::Read {
            part: name.to_owned(),
            error,
        };
        let mut mismatch = None;
        let mut duplicate = None;
        let first = self.first.clone();
        let seen = &self.seen;
        let mut check = |h: &PartialHeader| -> Result<(), PartialError> {
            if let Some((first_name, f)) = &first {
                let what = if h.scene_hash != f.scene_hash {
                    Some(format!(
                        "a different scene (content hash {:016x} here, {:016x} there)",
                        h.scene_hash, f.scene_hash
                    ))
                } else if (h.width, h.height) != (f.width, f.height) {
                    Some(format!(
                        "size {}x{} here, {}x{} there",
                        h.width, h.height, f.width, f.height
                    ))
                } else if h.spp != f.spp {
                    Some(format!("{} spp here, {} there", h.spp, f.spp))
                } else if h.settings != f.settings {
                    Some(first_difference(&h.settings, &f.settings))
                } else if h.share.count != f.share.count {
                    Some(format!(
                        "split in {} shares here, {} there",
                        h.share.count, f.share.count
                    ))
                } else {
                    None
                };
                if let Some(what) = what {
                    mismatch = Some((first_name.clone(), what));
                    return Err(PartialError::Header(String::new()));
                }
                if let Some(Some(earlier)) = seen.get(h.share.index as usize - 1) {
                    duplicate = Some((earlier.clone(), h.share));
                    return Err(PartialError::Header(String::new()));
                }
            }
            Ok(())
        };
        let mut film = self.film.take();
        let mut sums: Vec<ExactRgb> = Vec::new();
        let result = read_with(input, &mut check, &mut |at, block| match &mut film {
            Some(f) => {
                for (a, b) in f.sum[at..at + block.len()].iter_mut().zip(block) {
                    a.merge(b);
                }
            }
            None => sums.extend_from_slice(block),
        });
        if let Some((first, what)) = mismatch {
            return Err(MergeError::Mismatch {
                part: name.to_owned(),
                first,
                what,
            });
        }
        if let Some((earlier, share)) = duplicate {
            return Err(MergeError::Duplicate {
                part: name.to_owned(),
                earlier,
                share,
            });
        }
        let header = result.map_err(read_err)?;
        let n = header.share.samples(header.spp).len() as u32;
        match film {
            Some(mut f) => {
                f.n_samples += n;
                self.film = Some(f);
            }
            None => {
                self.film = Film::from_sums(header.width, header.height, n, sums);
                self.seen = vec![None; header.share.count as usize];
                self.first = Some((name.to_owned(), header.clone()));
            }
        }
        if let Some(slot) = self.seen.get_mut(header.share.index as usize - 1) {
            *slot = Some(name.to_owned());
        }
        Ok(())
    }

    /// The merged film, with the first part's header, once every share is
    /// in.
    pub fn finish(self) -> Result<(PartialHeader, Film), MergeError> {
        let (Some((_, header)), Some(film)) = (self.first, self.film) else {
            return Err(MergeError::Empty);
        };
        let missing: Vec<u32> = (1..=header.share.count)
            .filter(|k| self.seen.get(*k as usize - 1).is_none_or(Option::is_none))
            .collect();
        if !missing.is_empty() {
            return Err(MergeError::Missing {
                shares: missing,
                count: header.share.count,
            });
        }
        Ok((header, film))
    }
}

#[cfg(test)]
mod tests;
