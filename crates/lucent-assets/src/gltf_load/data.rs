//! glTF binary data: buffers (the GLB `BIN` chunk, an external file or a
//! base64 `data:` URI), buffer views and accessors. Every range is checked
//! against the bytes before anything is read or allocated, and errors are
//! messages that the caller prefixes with the JSON pointer of the part.

use crate::{AssetSource, normalize_path};
use gltf::accessor::sparse::IndexType;
use gltf::accessor::{Accessor, DataType, Dimensions};
use std::path::Path;

/// Every buffer's bytes, by buffer index.
pub(super) struct Buffers(pub(super) Vec<Vec<u8>>);

impl Buffers {
    /// Loads every buffer of `doc`; `blob` is the GLB's `BIN` chunk.
    pub(super) fn load(
        doc: &gltf::Document,
        mut blob: Option<Vec<u8>>,
        source: &dyn AssetSource,
        path: &Path,
    ) -> Result<Buffers, String> {
        let mut out = Vec::new();
        for b in doc.buffers() {
            let ptr = format!("/buffers/{}", b.index());
            let bytes = match b.source() {
                gltf::buffer::Source::Bin => blob
                    .take()
                    .ok_or_else(|| format!("{ptr}: refers to the GLB binary chunk, which the file does not have"))?,
                gltf::buffer::Source::Uri(uri) => read_uri(uri, source, path).map_err(|e| format!("{ptr}/uri: {e}"))?,
            };
            if bytes.len() < b.length() {
                return Err(format!(
                    "{ptr}: byteLength is {} but the data has only {} bytes",
                    b.length(),
                    bytes.len()
                ));
            }
            out.push(bytes);
        }
        Ok(Buffers(out))
    }

    /// The bytes of buffer view `view`, checked against its buffer.
    pub(super) fn view<'s>(&'s self, view: &gltf::buffer::View<'_>) -> Result<&'s [u8], String> {
        let buffer = self
            .0
            .get(view.buffer().index())
            .ok_or_else(|| format!("buffer view {} names a missing buffer", view.index()))?;
        let end = view.offset().checked_add(view.length());
        match end {
            Some(end) if end <= buffer.len() => Ok(&buffer[view.offset()..end]),
            _ => Err(format!(
                "buffer view {} (bytes {} to {}) reads past the end of buffer {} ({} bytes)",
                view.index(),
                view.offset(),
                view.offset().saturating_add(view.length()),
                view.buffer().index(),
                buffer.len()
            )),
        }
    }

    /// Total bytes of every buffer: no accessor can hold more elements.
    fn total(&self) -> usize {
        self.0.iter().map(Vec::len).sum()
    }

    /// The accessor's elements as `f32` components (`n` per element, the
    /// accessor's type), normalised integers mapped as the specification
    /// says, sparse substitution applied.
    pub(super) fn read_f32(&self, acc: &Accessor<'_>) -> Result<(Vec<f32>, usize), String> {
        let n = components(acc)?;
        let conv = converter(acc.data_type(), acc.normalized());
        let mut out = Vec::new();
        self.elements(acc, n, |bytes| {
            let size = component_size(acc.data_type());
            for c in bytes.chunks_exact(size).take(n) {
                out.push(conv(c));
            }
        })?;
        self.apply_sparse(acc, n, &mut out, conv)?;
        Ok((out, n))
    }

    /// A scalar accessor of unsigned integers (indices) as `u32`.
    pub(super) fn read_u32(&self, acc: &Accessor<'_>) -> Result<Vec<u32>, String> {
        if acc.dimensions() != Dimensions::Scalar {
            return Err(format!("accessor {} is not SCALAR", acc.index()));
        }
        let t = acc.data_type();
        if !matches!(t, DataType::U8 | DataType::U16 | DataType::U32) {
            return Err(format!(
                "accessor {} has component type {t:?}; indices must be unsigned bytes, shorts or ints",
                acc.index()
            ));
        }
        let mut out = Vec::new();
        self.elements(acc, 1, |bytes| out.push(uint(bytes)))?;
        self.apply_sparse(acc, 1, &mut out, uint)?;
        Ok(out)
    }

    /// Calls `each` with the bytes of every element of `acc` in order
    /// (zeros when it has no buffer view), after checking the range,
    /// alignment and stride.
    fn elements(&self, acc: &Accessor<'_>, n: usize, mut each: impl FnMut(&[u8])) -> Result<(), String> {
        let size = component_size(acc.data_type());
        let elem = size * n;
        let count = acc.count();
        let Some(view) = acc.view() else {
            // No view: all zeros (before sparse substitution); bounded by
            // the file's data so a huge count cannot allocate.
            if count.saturating_mul(elem) > self.total().max(1 << 16) {
                return Err(format!(
                    "accessor {} claims {count} elements without data, more than the file's buffers could hold",
                    acc.index()
                ));
            }
            let zero = vec![0u8; elem];
            for _ in 0..count {
                each(&zero);
            }
            return Ok(());
        };
        let bytes = self.view(&view)?;
        let stride = view.stride().unwrap_or(elem);
        if stride < elem || !stride.is_multiple_of(size) {
            return Err(format!(
                "buffer view {} has byteStride {stride}, which does not fit accessor {}'s {elem}-byte elements",
                view.index(),
                acc.index()
            ));
        }
        if !acc.offset().is_multiple_of(size) || !(view.offset() + acc.offset()).is_multiple_of(size) {
            return Err(format!(
                "accessor {} is misaligned: byte offset {} in buffer view {} (at {} in the buffer) is not a multiple of its {size}-byte components",
                acc.index(),
                acc.offset(),
                view.index(),
                view.offset() + acc.offset()
            ));
        }
        if count == 0 {
            return Ok(());
        }
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(acc.offset()))
            .and_then(|x| x.checked_add(elem));
        match end {
            Some(end) if end <= bytes.len() => {}
            _ => {
                return Err(format!(
                    "accessor {} reads past the end of buffer view {} ({count} elements of {elem} bytes every {stride} from byte {}, the view has {} bytes)",
                    acc.index(),
                    view.index(),
                    acc.offset(),
                    bytes.len()
                ));
            }
        }
        for i in 0..count {
            let start = acc.offset() + i * stride;
            each(&bytes[start..start + elem]);
        }
        Ok(())
    }

    /// Replaces the elements a sparse accessor names.
    fn apply_sparse<T: Copy>(
        &self,
        acc: &Accessor<'_>,
        n: usize,
        out: &mut [T],
        conv: impl Fn(&[u8]) -> T,
    ) -> Result<(), String> {
        let Some(sparse) = acc.sparse() else { return Ok(()) };
        let k = sparse.count();
        let (iv, vv) = (sparse.indices(), sparse.values());
        let isize = match iv.index_type() {
            IndexType::U8 => 1,
            IndexType::U16 => 2,
            IndexType::U32 => 4,
        };
        let size = component_size(acc.data_type());
        let ibytes = self.view(&iv.view())?;
        let vbytes = self.view(&vv.view())?;
        let fits = |bytes: &[u8], offset: usize, each: usize| {
            k.checked_mul(each)
                .and_then(|x| x.checked_add(offset))
                .is_some_and(|end| end <= bytes.len())
        };
        if !fits(ibytes, iv.offset(), isize) || !fits(vbytes, vv.offset(), size * n) {
            return Err(format!(
                "accessor {}'s sparse indices or values read past the end of their buffer view",
                acc.index()
            ));
        }
        for j in 0..k {
            let at = iv.offset() + j * isize;
            let target = uint(&ibytes[at..at + isize]) as usize;
            if target >= acc.count() {
                return Err(format!(
                    "accessor {}'s sparse index {target} is past its {} elements",
                    acc.index(),
                    acc.count()
                ));
            }
            for c in 0..n {
                let at = vv.offset() + (j * n + c) * size;
                if let Some(slot) = out.get_mut(target * n + c) {
                    *slot = conv(&vbytes[at..at + size]);
                }
            }
        }
        Ok(())
    }
}

/// Components per element of a vertex-data accessor (matrices are not).
fn components(acc: &Accessor<'_>) -> Result<usize, String> {
    match acc.dimensions() {
        Dimensions::Scalar => Ok(1),
        Dimensions::Vec2 => Ok(2),
        Dimensions::Vec3 => Ok(3),
        Dimensions::Vec4 => Ok(4),
        d => Err(format!(
            "accessor {} has type {d:?}, which is not vertex data",
            acc.index()
        )),
    }
}

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

/// Little-endian unsigned integer of 1, 2 or 4 bytes.
fn uint(b: &[u8]) -> u32 {
    b.iter().rev().fold(0u32, |acc, &x| (acc << 8) | u32::from(x))
}

/// How one component becomes an `f32`: floats as they are, normalised
/// integers as the specification's `c / max` (signed ones clamped at -1),
/// other integers as their value.
fn converter(t: DataType, normalized: bool) -> fn(&[u8]) -> f32 {
    match (t, normalized) {
        (DataType::F32, _) => |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        (DataType::U8, true) => |b| f32::from(b[0]) / 255.0,
        (DataType::U16, true) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        (DataType::I8, true) => |b| (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (DataType::I16, true) => |b| (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0),
        (DataType::U32, true) => |b| uint(b) as f32 / u32::MAX as f32,
        (DataType::U8, false) => |b| f32::from(b[0]),
        (DataType::U16, false) => |b| f32::from(u16::from_le_bytes([b[0], b[1]])),
        (DataType::I8, false) => |b| f32::from(b[0] as i8),
        (DataType::I16, false) => |b| f32::from(i16::from_le_bytes([b[0], b[1]])),
        (DataType::U32, false) => |b| uint(b) as f32,
    }
}

/// The bytes a URI names: a base64 `data:` URI or a file relative to the
/// glTF file (percent escapes decoded).
pub(super) fn read_uri(uri: &str, source: &dyn AssetSource, gltf_path: &Path) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((header, payload)) = rest.split_once(',') else {
            return Err("data URI without a comma".to_owned());
        };
        if !header.ends_with(";base64") {
            return Err("data URI is not base64".to_owned());
        }
        return decode_base64(payload).map_err(|at| format!("broken base64 in the data URI at character {at}"));
    }
    let file = percent_decode(uri).ok_or_else(|| format!("'{uri}' has a broken percent escape"))?;
    let dir = gltf_path.parent().unwrap_or(Path::new(""));
    let full = normalize_path(&dir.join(&file));
    source
        .read(&full)
        .map(std::borrow::Cow::into_owned)
        .map_err(|e| format!("cannot read '{file}': {e}"))
}

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Standard base64 (padding optional); the error is the position of the
/// first character that is not base64.
pub(super) fn decode_base64(s: &str) -> Result<Vec<u8>, usize> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' | b'-' => Some(62),
        b'/' | b'_' => Some(63),
        _ => None,
    };
    let trimmed = s.trim_end_matches('=');
    if s.len() - trimmed.len() > 2 || trimmed.len() % 4 == 1 {
        return Err(trimmed.len());
    }
    let mut out = Vec::with_capacity(trimmed.len() / 4 * 3 + 2);
    let (mut acc, mut bits) = (0u32, 0u32);
    for (i, c) in trimmed.bytes().enumerate() {
        acc = (acc << 6) | u32::from(value(c).ok_or(i)?);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_with_and_without_padding_and_locates_bad_characters() {
        assert_eq!(decode_base64("aGVsbG8="), Ok(b"hello".to_vec()));
        assert_eq!(decode_base64("aGVsbG8"), Ok(b"hello".to_vec()));
        assert_eq!(decode_base64("AAECAw=="), Ok(vec![0, 1, 2, 3]));
        assert_eq!(decode_base64(""), Ok(vec![]));
        assert_eq!(decode_base64("aGV*bG8="), Err(3));
        assert_eq!(decode_base64("aGVsb"), Err(5));
        assert_eq!(percent_decode("my%20file.bin").as_deref(), Some("my file.bin"));
        assert_eq!(percent_decode("bad%2"), None);
    }

    #[test]
    fn normalised_integers_follow_the_specification() {
        assert_eq!(converter(DataType::U8, true)(&[255]), 1.0);
        assert_eq!(converter(DataType::I8, true)(&[0x80]), -1.0);
        assert_eq!(converter(DataType::I16, true)(&[0xff, 0x7f]), 1.0);
        assert_eq!(converter(DataType::U16, false)(&[1, 1]), 257.0);
        assert_eq!(uint(&[1, 0, 0, 1]), 0x0100_0001);
    }
}
