//! Reading decimal numbers from OBJ and ASCII PLY, including the ways real
//! exporters print values that are not finite.
//!
//! Rust's `f32` parser already takes `nan`, `inf` and `infinity` in any
//! case and with a sign. Programs built with Microsoft's C runtime before
//! Visual Studio 2015 print them differently: `1.#INF`, `-1.#INF`,
//! `1.#IND` (the NaN of 0/0), `1.#QNAN`, `1.#SNAN`, padded with zeros to the
//! requested precision (`1.#INF00`) and, under `%e`, with an exponent
//! (`1.#INF00e+000`). Those are read as the infinities and NaNs they stand
//! for, so the loaders' usual handling of non-finite vertices applies (the
//! vertex is rejected with a warning, the rest of the file loads). Anything
//! else that is not a number (`3.1+e2`, `1.2.3`) stays an error.

/// The number `word` spells, or `None` when it is not one.
#[inline]
pub(crate) fn parse_f32(word: &[u8]) -> Option<f32> {
    parse_f32_str(std::str::from_utf8(word).ok()?)
}

/// [`parse_f32`] of a word already known to be text.
#[inline]
pub(crate) fn parse_f32_str(word: &str) -> Option<f32> {
    match word.parse() {
        Ok(v) => Some(v),
        Err(_) => msvc_non_finite(word.as_bytes()),
    }
}

/// `[+-]digits.#(INF|IND|QNAN|SNAN)0*` with an optional exponent
/// `e[+-]digits`, as MSVC's `printf` writes non-finite values (letters in
/// any case); infinities keep their sign.
#[cold]
fn msvc_non_finite(word: &[u8]) -> Option<f32> {
    let (negative, rest) = match word.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, word),
    };
    let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 {
        return None;
    }
    let rest = rest[digits..].strip_prefix(b".#")?;
    let name_len = rest.iter().take_while(|b| b.is_ascii_alphabetic()).count();
    let (name, mut rest) = rest.split_at(name_len);
    let value = if name.eq_ignore_ascii_case(b"INF") {
        if negative { f32::NEG_INFINITY } else { f32::INFINITY }
    } else if [&b"IND"[..], b"QNAN", b"SNAN"]
        .iter()
        .any(|n| name.eq_ignore_ascii_case(n))
    {
        f32::NAN
    } else {
        return None;
    };
    while let Some((b'0', tail)) = rest.split_first() {
        rest = tail;
    }
    if let Some((b'e' | b'E', exponent)) = rest.split_first() {
        let exponent = exponent
            .strip_prefix(b"+")
            .or_else(|| exponent.strip_prefix(b"-"))
            .unwrap_or(exponent);
        if exponent.is_empty() || !exponent.iter().all(u8::is_ascii_digit) {
            return None;
        }
        rest = &[];
    }
    rest.is_empty().then_some(value)
}

/// Non-finite spellings (MSVC's and the standard ones) that the loaders'
/// tests put in a vertex, which is then rejected.
#[cfg(test)]
pub(crate) const NON_FINITE_WORDS: [&str; 16] = [
    "1.#IND",
    "-1.#IND",
    "1.#QNAN",
    "-1.#QNAN",
    "1.#INF",
    "-1.#INF",
    "1.#INF00",
    "-1.#IND00",
    "1.#SNAN",
    "1.#INF00e+000",
    "nan",
    "NaN",
    "-inf",
    "INF",
    "Infinity",
    "-INFINITY",
];

/// Words like those that are not numbers, so a loader's error.
#[cfg(test)]
pub(crate) const NOT_NUMBERS: [&str; 6] = ["3.1+e2", "1.2.3", "1.#INFX", "1.#", "1.#NAN", "1.#INF01"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finite_and_standard_non_finite_spellings() {
        assert_eq!(parse_f32(b"-1.5e3"), Some(-1500.0));
        assert_eq!(parse_f32(b"42"), Some(42.0));
        for w in ["inf", "INF", "Infinity", "+inf", "iNfInItY"] {
            assert_eq!(parse_f32(w.as_bytes()), Some(f32::INFINITY), "{w}");
        }
        assert_eq!(parse_f32(b"-infinity"), Some(f32::NEG_INFINITY));
        for w in ["nan", "NaN", "NAN", "-nan"] {
            assert!(parse_f32(w.as_bytes()).is_some_and(f32::is_nan), "{w}");
        }
    }

    #[test]
    fn msvc_spellings() {
        for w in [
            "1.#INF",
            "1.#INF00",
            "+1.#INF",
            "1.#INF00e+000",
            "1.#inf",
            "1.#INF0000000",
        ] {
            assert_eq!(parse_f32(w.as_bytes()), Some(f32::INFINITY), "{w}");
        }
        for w in ["-1.#INF", "-1.#INF00", "-1.#INF00e+000"] {
            assert_eq!(parse_f32(w.as_bytes()), Some(f32::NEG_INFINITY), "{w}");
        }
        for w in [
            "1.#IND",
            "-1.#IND",
            "-1.#IND00",
            "1.#QNAN",
            "1.#QNAN0",
            "-1.#QNAN",
            "1.#SNAN",
            "1.#IND00e-000",
        ] {
            assert!(parse_f32(w.as_bytes()).is_some_and(f32::is_nan), "{w}");
        }
    }

    #[test]
    fn malformed_numbers_stay_errors() {
        for w in [
            "3.1+e2",
            "1.2.3",
            "",
            "-",
            "1.#",
            "1.#IN",
            "1.#INFX",
            "1.#INF01",
            "1.#INFe",
            "1.#INF00e+",
            "#INF",
            ".#INF",
            "1#INF",
            "1.#NAN",
            "infinit",
            "1.#INF 0",
            "x1.#INF",
            "1.#INF00e+00x",
            "nan0",
        ] {
            assert_eq!(parse_f32(w.as_bytes()), None, "{w}");
        }
        assert_eq!(parse_f32(b"\xff1"), None, "not UTF-8");
    }
}
