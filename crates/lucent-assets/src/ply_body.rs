//! The PLY body reader: streams ASCII or binary (both endians) element data
//! from a fixed buffer straight into typed vertex and index arrays.
//!
//! Nothing is allocated per element: ASCII lines are tokenised in place,
//! binary records are decoded at known offsets, and a face's indices go
//! through one reused scratch vector before being fanned into triangles.
//! Every failure carries its place: the line for ASCII, the byte offset
//! for binary.

use crate::Location;
use crate::ply::{Attributes, ElementPlan, Kind, N_SLOTS, PropPlan, Slot};
use crate::ply_header::Encoding;
use lucent_geom::{Vec2, Vec3};
use lucent_shading::color::srgb_to_linear;
use std::io::Read;

/// Bytes read from the file at a time.
const CHUNK: usize = 1 << 18;
/// Longest ASCII line accepted.
const MAX_LINE: usize = 1 << 24;

/// A failure and where it happened.
pub(crate) type BodyError = (Option<Location>, String);

/// A scalar type, as a small copyable tag.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    /// The type a header names: the PLY 1.0 names and their sized aliases.
    pub(crate) fn from_name(name: &[u8]) -> Option<Ty> {
        Some(match name {
            b"char" | b"int8" => Ty::I8,
            b"uchar" | b"uint8" => Ty::U8,
            b"short" | b"int16" => Ty::I16,
            b"ushort" | b"uint16" => Ty::U16,
            b"int" | b"int32" => Ty::I32,
            b"uint" | b"uint32" => Ty::U32,
            b"float" | b"float32" => Ty::F32,
            b"double" | b"float64" => Ty::F64,
            _ => return None,
        })
    }

    /// Bytes of one binary value.
    pub(crate) fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    pub(crate) fn is_integer(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }
}

/// A file read through a fixed buffer; `available()` is the unread part.
pub(crate) struct Input<'a> {
    reader: Box<dyn Read + 'a>,
    buf: Vec<u8>,
    pos: usize,
    end: usize,
    /// File offset of `buf[0]`.
    base: u64,
    eof: bool,
}

impl<'a> Input<'a> {
    pub(crate) fn new(reader: Box<dyn Read + 'a>) -> Self {
        Self {
            reader,
            buf: vec![0; CHUNK],
            pos: 0,
            end: 0,
            base: 0,
            eof: false,
        }
    }

    /// The bytes read but not consumed yet.
    #[inline]
    pub(crate) fn available(&self) -> &[u8] {
        &self.buf[self.pos..self.end]
    }

    /// Whether the file has no bytes left beyond `available()`.
    pub(crate) fn at_eof(&self) -> bool {
        self.eof
    }

    /// Marks `n <= available().len()` bytes as read.
    #[inline]
    pub(crate) fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.end);
    }

    /// File offset of the first unread byte.
    pub(crate) fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }

    /// Makes at least `n` bytes available, reading more of the file (and
    /// growing the buffer if `n` exceeds it); false if the file ends first.
    #[inline]
    pub(crate) fn fill(&mut self, n: usize) -> std::io::Result<bool> {
        if self.end - self.pos >= n {
            return Ok(true);
        }
        self.refill(n)
    }

    #[cold]
    fn refill(&mut self, n: usize) -> std::io::Result<bool> {
        self.buf.copy_within(self.pos..self.end, 0);
        self.base += self.pos as u64;
        self.end -= self.pos;
        self.pos = 0;
        if n > self.buf.len() {
            self.buf.resize(n, 0);
        }
        while self.end < n && !self.eof {
            match self.reader.read(&mut self.buf[self.end..]) {
                Ok(0) => self.eof = true,
                Ok(k) => self.end += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(self.end >= n)
    }
}

/// The mesh arrays being filled; optional ones exist only when the file
/// gives that attribute.
pub(crate) struct Buffers {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub colors: Option<Vec<Vec3>>,
    pub indices: Vec<[u32; 3]>,
    /// Faces with fewer than three vertices (no triangles made).
    pub short_faces: usize,
}

impl Buffers {
    /// Empty arrays sized from the header's counts (which were checked
    /// against the file size, so they are bounded by it).
    pub(crate) fn with_capacity(plans: &[ElementPlan], attributes: Attributes) -> Self {
        let count = |kind| plans.iter().find(|p| p.kind == kind).map_or(0, |p| p.count);
        let (n_v, n_f) = (count(Kind::Vertex), count(Kind::Face));
        Self {
            positions: Vec::with_capacity(n_v),
            normals: attributes.normals.then(|| Vec::with_capacity(n_v)),
            uvs: attributes.uvs.then(|| Vec::with_capacity(n_v)),
            colors: attributes.colors.then(|| Vec::with_capacity(n_v)),
            indices: Vec::with_capacity(n_f),
            short_faces: 0,
        }
    }

    #[inline]
    fn push_vertex(&mut self, r: &[f32; N_SLOTS]) {
        let at = |s: Slot| r[s as usize];
        self.positions.push(Vec3::new(at(Slot::X), at(Slot::Y), at(Slot::Z)));
        if let Some(n) = &mut self.normals {
            n.push(Vec3::new(at(Slot::Nx), at(Slot::Ny), at(Slot::Nz)).normalize_or_zero());
        }
        if let Some(uv) = &mut self.uvs {
            uv.push(Vec2::new(at(Slot::U), at(Slot::V)));
        }
        if let Some(c) = &mut self.colors {
            let ch = |s: Slot| srgb_to_linear(at(s).clamp(0.0, 1.0));
            c.push(Vec3::new(ch(Slot::R), ch(Slot::G), ch(Slot::B)));
        }
    }

    /// Fans a polygon into triangles `(0, k, k + 1)`, in file order.
    #[inline]
    fn push_face(&mut self, face: &[u32]) {
        match face {
            [a, b, c] => self.indices.push([*a, *b, *c]),
            [first, rest @ ..] if rest.len() >= 2 => {
                self.indices.extend(rest.windows(2).map(|w| [*first, w[0], w[1]]));
            }
            _ => self.short_faces += 1,
        }
    }
}

/// What the body reader needs to know about the file.
pub(crate) struct Body<'p> {
    pub plans: &'p [ElementPlan],
    pub encoding: Encoding,
    /// The header's vertex count: face indices must be below it.
    pub n_vertices: usize,
    /// Lines before the body (ASCII line numbers start after them).
    pub header_lines: usize,
    /// The byte that ends an ASCII line: `\n`, or `\r` in a file whose
    /// header ends in a lone CR (the other is then read as a space).
    pub line_end: u8,
    /// File length, to refuse lists longer than what is left.
    pub file_len: u64,
}

/// Reads every element of the body into `out`.
pub(crate) fn read_body(input: &mut Input<'_>, body: &Body<'_>, out: &mut Buffers) -> Result<(), BodyError> {
    let mut scratch: Vec<u32> = Vec::new();
    let mut line = body.header_lines;
    for plan in body.plans {
        match body.encoding {
            Encoding::Ascii => read_ascii_element(input, body, plan, &mut line, &mut scratch, out)?,
            Encoding::BinaryLittleEndian => read_binary_element(input, body, plan, false, &mut scratch, out)?,
            Encoding::BinaryBigEndian => read_binary_element(input, body, plan, true, &mut scratch, out)?,
        }
    }
    Ok(())
}

/// Whitespace-separated words of one line.
struct Words<'t> {
    text: &'t [u8],
}

impl<'t> Iterator for Words<'t> {
    type Item = &'t [u8];

    #[inline]
    fn next(&mut self) -> Option<&'t [u8]> {
        let start = self.text.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.text[start..];
        let len = rest.iter().position(|b| b.is_ascii_whitespace()).unwrap_or(rest.len());
        self.text = &rest[len..];
        Some(&rest[..len])
    }
}

/// A decimal integer (optional sign, at most 18 digits).
#[inline]
fn parse_int(word: &[u8]) -> Option<i64> {
    let (negative, digits) = match word.split_first() {
        Some((b'-', d)) => (true, d),
        Some((b'+', d)) => (false, d),
        _ => (false, word),
    };
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    let mut v: i64 = 0;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        v = v * 10 + i64::from(d - b'0');
    }
    Some(if negative { -v } else { v })
}

fn show(word: &[u8]) -> String {
    let s = String::from_utf8_lossy(word);
    if s.len() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// Makes the next line, ended by `line_end`, available; returns its length
/// without the line break and with it, or `None` at the end of the file.
fn next_line(input: &mut Input<'_>, line_end: u8) -> Result<Option<(usize, usize)>, String> {
    let mut searched = 0;
    loop {
        let avail = input.available();
        if let Some(nl) = avail[searched..].iter().position(|&b| b == line_end) {
            let len = searched + nl;
            return Ok(Some((len, len + 1)));
        }
        if input.at_eof() {
            return Ok((!avail.is_empty()).then_some((avail.len(), avail.len())));
        }
        if avail.len() >= MAX_LINE {
            return Err(format!("a line longer than {MAX_LINE} bytes"));
        }
        searched = avail.len();
        // Grow geometrically, so a long line costs linear time.
        let want = (2 * avail.len()).max(CHUNK / 2);
        input.fill(want).map_err(|e| format!("read error: {e}"))?;
    }
}

fn read_ascii_element(
    input: &mut Input<'_>,
    body: &Body<'_>,
    plan: &ElementPlan,
    line: &mut usize,
    scratch: &mut Vec<u32>,
    out: &mut Buffers,
) -> Result<(), BodyError> {
    for entry in 0..plan.count {
        // Skip blank lines between entries.
        let (len, total) = loop {
            let next = next_line(input, body.line_end).map_err(|m| (Some(Location::Line(*line + 1)), m))?;
            let Some((len, total)) = next else {
                return Err((
                    Some(Location::Line(*line + 1)),
                    format!(
                        "truncated: the file ends after {entry} of {} '{}' entries",
                        plan.count, plan.name
                    ),
                ));
            };
            *line += 1;
            if input.available()[..len].iter().all(u8::is_ascii_whitespace) {
                input.consume(total);
                continue;
            }
            break (len, total);
        };
        let text = &input.available()[..len];
        let mut rec = [0.0f32; N_SLOTS];
        parse_ascii_entry(text, body, plan, &mut rec, scratch).map_err(|m| (Some(Location::Line(*line)), m))?;
        match plan.kind {
            Kind::Vertex => out.push_vertex(&rec),
            Kind::Face if has_indices(plan) => out.push_face(scratch),
            _ => {}
        }
        input.consume(total);
    }
    Ok(())
}

fn parse_ascii_entry(
    text: &[u8],
    body: &Body<'_>,
    plan: &ElementPlan,
    rec: &mut [f32; N_SLOTS],
    scratch: &mut Vec<u32>,
) -> Result<(), String> {
    let mut words = Words { text };
    let mut next = |what: &str| {
        words.next().ok_or_else(|| {
            format!(
                "the line ends before {what} of element '{}' (fewer values than the header declares)",
                plan.name
            )
        })
    };
    for p in &plan.props {
        match *p {
            PropPlan::Scalar { slot, scale, .. } => {
                let word = next("a property")?;
                if let Some(s) = slot {
                    let v =
                        crate::number::parse_f32(word).ok_or_else(|| format!("'{}' is not a number", show(word)))?;
                    rec[s as usize] = v * scale;
                }
            }
            PropPlan::List { indices, .. } => {
                let word = next("a list count")?;
                let n = parse_int(word)
                    .filter(|n| *n >= 0)
                    .ok_or_else(|| format!("'{}' is not a list length", show(word)))?;
                if indices {
                    scratch.clear();
                }
                for _ in 0..n {
                    let word = next("a list entry")?;
                    if indices {
                        let i = parse_int(word).ok_or_else(|| format!("'{}' is not a vertex index", show(word)))?;
                        scratch.push(check_index(i, body.n_vertices)?);
                    }
                }
            }
        }
    }
    if words.next().is_some() {
        return Err(format!(
            "more values than the header declares for element '{}'",
            plan.name
        ));
    }
    Ok(())
}

fn has_indices(plan: &ElementPlan) -> bool {
    plan.props
        .iter()
        .any(|p| matches!(p, PropPlan::List { indices: true, .. }))
}

#[inline]
fn check_index(i: i64, n_vertices: usize) -> Result<u32, String> {
    if i >= 0 && (i as u64) < n_vertices as u64 {
        Ok(i as u32)
    } else {
        Err(format!("vertex index {i} is out of range ({n_vertices} vertices)"))
    }
}

macro_rules! decode {
    ($b:expr, $t:ty, $n:literal, $big:expr) => {{
        let a = $b.first_chunk::<$n>().copied().unwrap_or([0; $n]);
        if $big {
            <$t>::from_be_bytes(a)
        } else {
            <$t>::from_le_bytes(a)
        }
    }};
}

/// The value at the start of `b` (which holds at least `ty.size()` bytes).
#[inline]
fn read_f32(b: &[u8], ty: Ty, big: bool) -> f32 {
    match ty {
        Ty::I8 => decode!(b, i8, 1, big) as f32,
        Ty::U8 => decode!(b, u8, 1, big) as f32,
        Ty::I16 => decode!(b, i16, 2, big) as f32,
        Ty::U16 => decode!(b, u16, 2, big) as f32,
        Ty::I32 => decode!(b, i32, 4, big) as f32,
        Ty::U32 => decode!(b, u32, 4, big) as f32,
        Ty::F32 => decode!(b, f32, 4, big),
        Ty::F64 => decode!(b, f64, 8, big) as f32,
    }
}

/// The integer at the start of `b`; float types (refused by the planner
/// for counts and indices) read as -1.
#[inline]
fn read_int(b: &[u8], ty: Ty, big: bool) -> i64 {
    match ty {
        Ty::I8 => decode!(b, i8, 1, big).into(),
        Ty::U8 => decode!(b, u8, 1, big).into(),
        Ty::I16 => decode!(b, i16, 2, big).into(),
        Ty::U16 => decode!(b, u16, 2, big).into(),
        Ty::I32 => decode!(b, i32, 4, big).into(),
        Ty::U32 => decode!(b, u32, 4, big).into(),
        Ty::F32 | Ty::F64 => -1,
    }
}

fn read_binary_element(
    input: &mut Input<'_>,
    body: &Body<'_>,
    plan: &ElementPlan,
    big: bool,
    scratch: &mut Vec<u32>,
    out: &mut Buffers,
) -> Result<(), BodyError> {
    let truncated = |input: &Input<'_>, entry: usize| {
        (
            Some(Location::Byte(input.offset())),
            format!(
                "truncated: the file ends inside '{}' entry {entry} of {}",
                plan.name, plan.count
            ),
        )
    };
    let io = |input: &Input<'_>, e: std::io::Error| (Some(Location::Byte(input.offset())), format!("read error: {e}"));
    // Entries of scalars only have one size: decode them at fixed offsets.
    let fixed: Option<usize> = plan
        .props
        .iter()
        .map(|p| match p {
            PropPlan::Scalar { ty, .. } => Some(ty.size()),
            PropPlan::List { .. } => None,
        })
        .sum();
    if let Some(size) = fixed {
        let mut used = Vec::new();
        let mut offset = 0;
        for p in &plan.props {
            if let PropPlan::Scalar { ty, slot, scale } = *p {
                if let Some(s) = slot {
                    used.push((offset, ty, s as usize, scale));
                }
                offset += ty.size();
            }
        }
        let mut rec = [0.0f32; N_SLOTS];
        for entry in 0..plan.count {
            if !input.fill(size).map_err(|e| io(input, e))? {
                return Err(truncated(input, entry));
            }
            let bytes = input.available();
            for &(offset, ty, slot, scale) in &used {
                rec[slot] = read_f32(&bytes[offset..], ty, big) * scale;
            }
            if plan.kind == Kind::Vertex {
                out.push_vertex(&rec);
            }
            input.consume(size);
        }
        return Ok(());
    }
    let mut rec = [0.0f32; N_SLOTS];
    for entry in 0..plan.count {
        for p in &plan.props {
            match *p {
                PropPlan::Scalar { ty, slot, scale } => {
                    if !input.fill(ty.size()).map_err(|e| io(input, e))? {
                        return Err(truncated(input, entry));
                    }
                    if let Some(s) = slot {
                        rec[s as usize] = read_f32(input.available(), ty, big) * scale;
                    }
                    input.consume(ty.size());
                }
                PropPlan::List { count, item, indices } => {
                    if !input.fill(count.size()).map_err(|e| io(input, e))? {
                        return Err(truncated(input, entry));
                    }
                    let n = read_int(input.available(), count, big);
                    let at = Some(Location::Byte(input.offset()));
                    if n < 0 {
                        return Err((at, format!("negative list length {n} in '{}'", plan.name)));
                    }
                    input.consume(count.size());
                    let n = n as u64;
                    let len = n * item.size() as u64;
                    if len > body.file_len.saturating_sub(input.offset()) {
                        return Err((
                            at,
                            format!(
                                "truncated: a list of {n} entries runs past the end of the file ('{}' entry {entry} of {})",
                                plan.name, plan.count
                            ),
                        ));
                    }
                    if !input.fill(len as usize).map_err(|e| io(input, e))? {
                        return Err(truncated(input, entry));
                    }
                    if indices {
                        scratch.clear();
                        let step = item.size();
                        for k in 0..n as usize {
                            let i = read_int(&input.available()[k * step..], item, big);
                            let v = check_index(i, body.n_vertices)
                                .map_err(|m| (Some(Location::Byte(input.offset() + (k * step) as u64)), m))?;
                            scratch.push(v);
                        }
                    }
                    input.consume(len as usize);
                }
            }
        }
        match plan.kind {
            Kind::Vertex => out.push_vertex(&rec),
            Kind::Face if has_indices(plan) => out.push_face(scratch),
            _ => {}
        }
    }
    Ok(())
}
