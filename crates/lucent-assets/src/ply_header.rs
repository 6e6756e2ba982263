//! The PLY header: where it ends, and its grammar.
//!
//! Lucent parses the header itself (it used ply-rs for this until the
//! files real exporters write showed what that cost): lines may end in
//! `\n`, `\r\n` or a lone `\r` (Rhinoceros 6 and old Mac tools write CR
//! only), words are separated by any run of spaces or tabs and a line may
//! be padded on either side, and a line that starts with no PLY keyword
//! (Blender 2.47 wrote its banner as a bare line) is read as a comment
//! with a warning that quotes it. The rest stays strict: the `format`
//! line, `element` and `property` declarations must be well formed, and
//! every error names the file's own line. Element counts are checked
//! against the file's size by the caller.

use crate::ply_body::{Input, Ty};
use crate::{AssetError, LoadReport, Location};
use std::collections::HashSet;
use std::path::Path;

/// Longest header accepted; real headers are a few hundred bytes.
const MAX_HEADER: usize = 1 << 20;

/// Stray (keyword-less) header lines quoted one warning each; more are
/// counted in one last warning.
const QUOTED_STRAY_LINES: usize = 5;

/// Characters of a stray line quoted in its warning.
const QUOTE_CHARS: usize = 80;

/// How the body is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A property's type: a scalar, or a list with its count and item types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PropertyType {
    Scalar(Ty),
    List(Ty, Ty),
}

/// One `property` line.
#[derive(Clone, Debug)]
pub(crate) struct PropertyDef {
    pub name: String,
    pub ty: PropertyType,
    /// Its line in the file, from 1.
    pub line: usize,
}

/// One `element` line and the properties declared after it.
#[derive(Clone, Debug)]
pub(crate) struct ElementDef {
    pub name: String,
    pub count: usize,
    pub properties: Vec<PropertyDef>,
    /// Its line in the file, from 1.
    pub line: usize,
}

impl ElementDef {
    /// The property called `name`, if declared (names are unique).
    pub(crate) fn property(&self, name: &str) -> Option<&PropertyDef> {
        self.properties.iter().find(|p| p.name == name)
    }
}

/// A parsed header.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub encoding: Encoding,
    /// In file order, which is the body's order.
    pub elements: Vec<ElementDef>,
    /// The `end_header` line.
    pub end_line: usize,
}

/// Where the header ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct HeaderSpan {
    /// Bytes of the header, up to and including the `end_header` line's
    /// own line end: the body starts here.
    pub len: usize,
    /// Lines of the header (ASCII body lines are numbered after them).
    pub lines: usize,
    /// The byte that ends an ASCII body's lines: `\r` when the
    /// `end_header` line ended in a lone CR, `\n` otherwise (a CR before it
    /// is then part of the line, read as a space).
    pub body_line_end: u8,
}

/// The line end found after a header line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LineEnd {
    Lf,
    CrLf,
    Cr,
}

/// Finds the `end_header` line, reading as much of `input` as it takes
/// (at most [`MAX_HEADER`] bytes). Fails fast when the file does not start
/// with a `ply` line.
///
/// The end of the `end_header` line decides where a binary body begins:
/// after `\n`, after `\r\n`, or after a lone `\r`. When a `\r` is followed
/// by a `\n` byte, the header's first line settles which it is: in a file
/// whose `ply` line ends in a lone CR, the `\n` is the body's first byte.
pub(crate) fn find_header_end(input: &mut Input<'_>, path: &Path) -> Result<HeaderSpan, AssetError> {
    let io = |error| AssetError::Io {
        path: path.to_owned(),
        error,
    };
    input.fill(4096).map_err(io)?;
    let first = input.available();
    let first = &first[first.iter().take_while(|b| matches!(b, b' ' | b'\t')).count()..];
    let is_ply = first
        .strip_prefix(b"ply")
        .is_some_and(|rest| rest.first().is_none_or(u8::is_ascii_whitespace));
    if !is_ply {
        return Err(AssetError::at(
            path,
            Location::Line(1),
            "not a PLY file (it does not start with a 'ply' line)",
        ));
    }
    let mut line_start = 0;
    let mut line_no = 0;
    let mut first_end: Option<LineEnd> = None;
    loop {
        let avail = input.available();
        match avail[line_start..].iter().position(|&b| b == b'\n' || b == b'\r') {
            Some(k) => {
                let end = line_start + k;
                let line_end = if avail[end] == b'\n' {
                    LineEnd::Lf
                } else {
                    match avail.get(end + 1) {
                        Some(b'\n') => LineEnd::CrLf,
                        Some(_) => LineEnd::Cr,
                        None if input.at_eof() => LineEnd::Cr,
                        None => {
                            // Whether a `\n` follows is in the next read.
                            let want = avail.len() + 1;
                            input.fill(want).map_err(io)?;
                            continue;
                        }
                    }
                };
                line_no += 1;
                let first_end = *first_end.get_or_insert(line_end);
                let line = &avail[line_start..end];
                if line_no == 1 && line.trim_ascii() != b"ply" {
                    return Err(AssetError::at(
                        path,
                        Location::Line(1),
                        "not a PLY file (it does not start with a 'ply' line)",
                    ));
                }
                if line.trim_ascii() == b"end_header" {
                    let (len, body_line_end) = match (line_end, first_end) {
                        (LineEnd::Lf, _) => (1, b'\n'),
                        (LineEnd::CrLf, LineEnd::Cr) | (LineEnd::Cr, _) => (1, b'\r'),
                        (LineEnd::CrLf, _) => (2, b'\n'),
                    };
                    return Ok(HeaderSpan {
                        len: end + len,
                        lines: line_no,
                        body_line_end,
                    });
                }
                line_start = end + if line_end == LineEnd::CrLf { 2 } else { 1 };
            }
            None if input.at_eof() => {
                if avail[line_start..].trim_ascii() == b"end_header" {
                    return Ok(HeaderSpan {
                        len: avail.len(),
                        lines: line_no + 1,
                        body_line_end: b'\n',
                    });
                }
                return Err(AssetError::at(
                    path,
                    Location::Line(line_no + usize::from(line_start < avail.len())),
                    "the file ends inside the header (no end_header line)",
                ));
            }
            None if avail.len() >= MAX_HEADER => {
                return Err(AssetError::at(
                    path,
                    Location::Line(line_no + 1),
                    format!("no end_header line in the first {MAX_HEADER} bytes"),
                ));
            }
            None => {
                let want = (2 * avail.len()).max(4096);
                input.fill(want).map_err(io)?;
            }
        }
    }
}

/// The lines of `bytes`, each ended by `\n`, `\r\n` or a lone `\r`.
fn lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = bytes;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let end = rest
            .iter()
            .position(|&b| b == b'\n' || b == b'\r')
            .unwrap_or(rest.len());
        let line = &rest[..end];
        let skip = match rest.get(end..end + 2) {
            Some(b"\r\n") => 2,
            _ => (end + 1).min(rest.len()) - end,
        };
        rest = &rest[end + skip..];
        Some(line)
    })
}

/// Parses the header found by [`find_header_end`] (`bytes` ends with the
/// `end_header` line). Keyword-less lines become warnings in `report`.
pub(crate) fn parse_header(bytes: &[u8], path: &Path, report: &mut LoadReport) -> Result<Header, AssetError> {
    let mut format: Option<(Encoding, usize)> = None;
    let mut elements: Vec<ElementDef> = Vec::new();
    // Sets: a long header of many elements or properties must not take
    // quadratic time.
    let mut element_names: HashSet<String> = HashSet::new();
    let mut property_names: HashSet<String> = HashSet::new();
    let mut stray_lines = 0usize;
    let mut end_line = 0;
    for (i, line) in lines(bytes).enumerate() {
        let line_no = i + 1;
        end_line = line_no;
        let at = |message: String| AssetError::at(path, Location::Line(line_no), message);
        let mut words = line.split(u8::is_ascii_whitespace).filter(|w| !w.is_empty());
        let Some(keyword) = words.next() else { continue };
        if line_no == 1 {
            // The `ply` line, which `find_header_end` checked.
            continue;
        }
        match keyword {
            b"format" => {
                let (Some(encoding), Some(version)) = (words.next(), words.next()) else {
                    return Err(at(
                        "the format line needs an encoding and a version, as in 'format binary_little_endian 1.0'"
                            .to_owned(),
                    ));
                };
                let encoding = match encoding {
                    b"ascii" => Encoding::Ascii,
                    b"binary_little_endian" => Encoding::BinaryLittleEndian,
                    b"binary_big_endian" => Encoding::BinaryBigEndian,
                    other => return Err(at(format!("unknown PLY format '{}'", show(other)))),
                };
                if version != b"1.0" {
                    return Err(at(format!(
                        "unsupported PLY format version '{}' (only 1.0 exists)",
                        show(version)
                    )));
                }
                if let Some(extra) = words.next() {
                    return Err(at(format!("unexpected '{}' after the format", show(extra))));
                }
                match format {
                    Some((earlier, earlier_line)) if earlier != encoding => {
                        return Err(at(format!("this format contradicts the one on line {earlier_line}")));
                    }
                    Some(_) => {}
                    None => format = Some((encoding, line_no)),
                }
            }
            b"comment" | b"obj_info" => {}
            b"element" => {
                check_has_properties(elements.last(), path)?;
                let Some(name) = words.next().map(show_all) else {
                    return Err(at("the element has no name".to_owned()));
                };
                let Some(count) = words.next() else {
                    return Err(at(format!("element '{name}' has no count")));
                };
                let count = parse_count(count).map_err(at)?;
                if let Some(extra) = words.next() {
                    return Err(at(format!("unexpected '{}' after element '{name}'", show(extra))));
                }
                if !element_names.insert(name.clone()) {
                    return Err(at(format!("element '{name}' is declared twice")));
                }
                property_names.clear();
                elements.push(ElementDef {
                    name,
                    count,
                    properties: Vec::new(),
                    line: line_no,
                });
            }
            b"property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(at("a property before any element".to_owned()));
                };
                let ty = match words.next() {
                    None => return Err(at("the property has no type".to_owned())),
                    Some(b"list") => {
                        let count = scalar_type(words.next()).map_err(at)?;
                        let item = scalar_type(words.next()).map_err(at)?;
                        PropertyType::List(count, item)
                    }
                    word => PropertyType::Scalar(scalar_type(word).map_err(at)?),
                };
                let Some(name) = words.next().map(show_all) else {
                    return Err(at("the property has no name".to_owned()));
                };
                if let Some(extra) = words.next() {
                    return Err(at(format!("unexpected '{}' after property '{name}'", show(extra))));
                }
                if !property_names.insert(name.clone()) {
                    return Err(at(format!(
                        "property '{name}' is declared twice in element '{}'",
                        element.name
                    )));
                }
                element.properties.push(PropertyDef {
                    name,
                    ty,
                    line: line_no,
                });
            }
            b"end_header" if words.next().is_none() => {
                check_has_properties(elements.last(), path)?;
            }
            _ => {
                stray_lines += 1;
                if stray_lines <= QUOTED_STRAY_LINES {
                    report.warn(
                        path,
                        format!(
                            "line {line_no}: a header line without a PLY keyword, read as a comment: '{}'",
                            quote(line.trim_ascii())
                        ),
                    );
                }
            }
        }
    }
    if stray_lines > QUOTED_STRAY_LINES {
        report.warn(
            path,
            format!(
                "{} more header lines without a PLY keyword, read as comments",
                stray_lines - QUOTED_STRAY_LINES
            ),
        );
    }
    let Some((encoding, _)) = format else {
        return Err(AssetError::at(
            path,
            Location::Line(end_line),
            "the header has no format line (such as 'format binary_little_endian 1.0')",
        ));
    };
    Ok(Header {
        encoding,
        elements,
        end_line,
    })
}

/// Fails when the element declared last has no property yet.
fn check_has_properties(last: Option<&ElementDef>, path: &Path) -> Result<(), AssetError> {
    match last {
        Some(e) if e.properties.is_empty() => Err(AssetError::at(
            path,
            Location::Line(e.line),
            format!("element '{}' has no properties", e.name),
        )),
        _ => Ok(()),
    }
}

/// An element count: decimal digits that fit a `usize`.
fn parse_count(word: &[u8]) -> Result<usize, String> {
    if !word.iter().all(u8::is_ascii_digit) {
        return Err(format!("element count '{}' is not a whole number", show(word)));
    }
    show_all(word)
        .parse()
        .map_err(|_| format!("number {} in the header is too large", show(word)))
}

/// A scalar type by its PLY name or sized alias.
fn scalar_type(word: Option<&[u8]>) -> Result<Ty, String> {
    let Some(word) = word else {
        return Err("the property's type is incomplete ('list' needs a count and an item type)".to_owned());
    };
    Ty::from_name(word).ok_or_else(|| {
        format!(
            "unknown property type '{}' (expected char, uchar, short, ushort, int, uint, float, double, \
             or int8 ... float64)",
            show(word)
        )
    })
}

fn show_all(word: &[u8]) -> String {
    String::from_utf8_lossy(word).into_owned()
}

/// A word for an error message, cut to 40 characters.
fn show(word: &[u8]) -> String {
    cut(&String::from_utf8_lossy(word), 40)
}

/// A stray line for its warning, cut to [`QUOTE_CHARS`] characters.
fn quote(line: &[u8]) -> String {
    cut(&String::from_utf8_lossy(line), QUOTE_CHARS)
}

fn cut(s: &str, chars: usize) -> String {
    match s.char_indices().nth(chars) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_end_in_lf_crlf_or_cr() {
        let got: Vec<&[u8]> = lines(b"a\nb\r\nc\rd\r\re").collect();
        assert_eq!(got, [&b"a"[..], b"b", b"c", b"d", b"", b"e"]);
        let got: Vec<&[u8]> = lines(b"a\r").collect();
        assert_eq!(got, [&b"a"[..]]);
        assert_eq!(lines(b"").count(), 0);
    }

    #[test]
    fn cut_keeps_whole_characters() {
        assert_eq!(cut("abc", 2), "ab...");
        assert_eq!(cut("ab", 2), "ab");
        assert_eq!(cut("éé€", 2), "éé...");
    }
}
