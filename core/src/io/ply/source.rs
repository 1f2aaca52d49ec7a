//! Value sources over a PLY body: a binary cursor (either byte order) and an ascii tokenizer that
//! counts lines, behind one trait so the element loops are written once and monomorphised.

use std::path::Path;

use super::header::Scalar;
use crate::io::IoError;

/// Why a value could not be read; the caller adds which element and property it was.
#[derive(Debug)]
pub(crate) enum Fail {
    /// The body ended before the value.
    Eof { needed: usize },
    /// An ascii token that is not a number.
    NotNumber(String),
}

/// A stream of scalar values in a PLY body.
pub(crate) trait Source {
    /// Reads one value of type `ty`, widened to f64 (exact for every PLY type).
    fn read(&mut self, ty: Scalar) -> Result<f64, Fail>;
    /// Skips `n` values of type `ty` without interpreting them.
    fn skip(&mut self, ty: Scalar, n: usize) -> Result<(), Fail>;
    /// The largest number of `ty` values the rest of the body could possibly hold, used to
    /// refuse absurd list counts before looping over them.
    fn capacity(&self, ty: Scalar) -> usize;
    /// An error located at the current position (byte offset, or line of the last token).
    fn error(&self, path: &Path, msg: String) -> IoError;
    /// Bytes left after the last element that are not whitespace padding.
    fn trailing(&self) -> usize;
}

/// A binary body; `BE` selects big-endian.
pub(crate) struct Binary<'a, const BE: bool> {
    data: &'a [u8],
    pos: usize,
    /// Offset of the body in the file, so errors give file offsets.
    base: u64,
}

impl<'a, const BE: bool> Binary<'a, BE> {
    pub(crate) fn new(data: &'a [u8], base: usize) -> Self {
        Self { data, pos: 0, base: base as u64 }
    }

    #[inline(always)]
    fn take<const N: usize>(&mut self) -> Result<[u8; N], Fail> {
        match self.data.get(self.pos..self.pos + N) {
            Some(b) => {
                self.pos += N;
                let mut a = [0u8; N];
                a.copy_from_slice(b);
                Ok(a)
            }
            None => Err(Fail::Eof { needed: N }),
        }
    }
}

macro_rules! num {
    ($be:expr, $t:ty, $b:expr) => {
        if $be { <$t>::from_be_bytes($b) } else { <$t>::from_le_bytes($b) }
    };
}

impl<const BE: bool> Source for Binary<'_, BE> {
    #[inline(always)]
    fn read(&mut self, ty: Scalar) -> Result<f64, Fail> {
        Ok(match ty {
            Scalar::I8 => f64::from(num!(BE, i8, self.take::<1>()?)),
            Scalar::U8 => f64::from(num!(BE, u8, self.take::<1>()?)),
            Scalar::I16 => f64::from(num!(BE, i16, self.take::<2>()?)),
            Scalar::U16 => f64::from(num!(BE, u16, self.take::<2>()?)),
            Scalar::I32 => f64::from(num!(BE, i32, self.take::<4>()?)),
            Scalar::U32 => f64::from(num!(BE, u32, self.take::<4>()?)),
            Scalar::F32 => f64::from(num!(BE, f32, self.take::<4>()?)),
            Scalar::F64 => num!(BE, f64, self.take::<8>()?),
        })
    }

    #[inline]
    fn skip(&mut self, ty: Scalar, n: usize) -> Result<(), Fail> {
        let bytes = ty.size().saturating_mul(n);
        if bytes > self.data.len() - self.pos {
            return Err(Fail::Eof { needed: bytes });
        }
        self.pos += bytes;
        Ok(())
    }

    fn capacity(&self, ty: Scalar) -> usize {
        (self.data.len() - self.pos) / ty.size()
    }

    fn error(&self, path: &Path, msg: String) -> IoError {
        IoError::byte(path, self.base + self.pos as u64, msg)
    }

    fn trailing(&self) -> usize {
        self.data.len() - self.pos
    }
}

/// An ascii body: whitespace-separated tokens, elements need not start on new lines.
pub(crate) struct Ascii<'a> {
    data: &'a [u8],
    pos: usize,
    /// 1-based file line of the last token read (or of the position, before the first token).
    line: u64,
}

impl<'a> Ascii<'a> {
    /// `first_line` is the file line the body starts on.
    pub(crate) fn new(data: &'a [u8], first_line: u64) -> Self {
        Self { data, pos: 0, line: first_line }
    }

    /// The next token, or `None` at the end of the body.
    #[inline]
    fn token(&mut self) -> Option<&'a [u8]> {
        let d = self.data;
        let mut p = self.pos;
        let mut line = self.line;
        while p < d.len() && d[p].is_ascii_whitespace() {
            if d[p] == b'\n' {
                line += 1;
            }
            p += 1;
        }
        if p == d.len() {
            // At the end, errors keep pointing at the line of the last token.
            self.pos = p;
            return None;
        }
        self.line = line;
        let start = p;
        while p < d.len() && !d[p].is_ascii_whitespace() {
            p += 1;
        }
        self.pos = p;
        Some(&d[start..p])
    }
}

/// Parses an ascii number. Integers (the bulk of face lists) take a fast path; everything else,
/// including exponents and `nan`/`inf` (caught later where they matter), goes through the
/// standard library's correctly rounded parser.
#[inline]
fn parse_number(tok: &[u8]) -> Option<f64> {
    let (neg, digits) = match tok.first() {
        Some(b'-') => (true, &tok[1..]),
        Some(b'+') => (false, &tok[1..]),
        _ => (false, tok),
    };
    if !digits.is_empty() && digits.len() <= 15 && digits.iter().all(u8::is_ascii_digit) {
        let mut v: u64 = 0;
        for &c in digits {
            v = v * 10 + u64::from(c - b'0');
        }
        // Exact: 15 decimal digits stay below 2^53.
        let v = v as f64;
        return Some(if neg { -v } else { v });
    }
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

impl Source for Ascii<'_> {
    #[inline]
    fn read(&mut self, _ty: Scalar) -> Result<f64, Fail> {
        let tok = self.token().ok_or(Fail::Eof { needed: 1 })?;
        parse_number(tok).ok_or_else(|| {
            let shown: String = String::from_utf8_lossy(tok).chars().take(40).collect();
            Fail::NotNumber(shown)
        })
    }

    fn skip(&mut self, _ty: Scalar, n: usize) -> Result<(), Fail> {
        for _ in 0..n {
            self.token().ok_or(Fail::Eof { needed: 1 })?;
        }
        Ok(())
    }

    fn capacity(&self, _ty: Scalar) -> usize {
        // Each value is at least one character plus a separator (none after the last one).
        (self.data.len() - self.pos).div_ceil(2)
    }

    fn error(&self, path: &Path, msg: String) -> IoError {
        IoError::line(path, self.line, msg)
    }

    fn trailing(&self) -> usize {
        self.data[self.pos..].iter().filter(|b| !b.is_ascii_whitespace()).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_parse_exactly() {
        assert_eq!(parse_number(b"-12"), Some(-12.0));
        assert_eq!(parse_number(b"+7"), Some(7.0));
        assert_eq!(parse_number(b"500000.125"), Some(500000.125));
        assert_eq!(parse_number(b"1e3"), Some(1000.0));
        assert_eq!(parse_number(b"12345678901234567890"), Some(12345678901234567890.0));
        assert!(parse_number(b"nan").is_some_and(f64::is_nan));
        assert_eq!(parse_number(b"abc"), None);
        assert_eq!(parse_number(b"-"), None);
    }

    #[test]
    fn ascii_counts_lines() {
        let mut a = Ascii::new(b"1 2\n\n3\r\n x", 10);
        assert_eq!(a.read(Scalar::F32).unwrap(), 1.0);
        assert_eq!(a.read(Scalar::F32).unwrap(), 2.0);
        assert_eq!(a.line, 10);
        assert_eq!(a.read(Scalar::F32).unwrap(), 3.0);
        assert_eq!(a.line, 12);
        assert!(matches!(a.read(Scalar::F32), Err(Fail::NotNumber(t)) if t == "x"));
        assert_eq!(a.line, 13);
        assert!(matches!(a.read(Scalar::F32), Err(Fail::Eof { .. })));
    }

    #[test]
    fn binary_reads_both_orders() {
        let le = 0x0102_0304u32.to_le_bytes();
        let be = 0x0102_0304u32.to_be_bytes();
        assert_eq!(Binary::<false>::new(&le, 0).read(Scalar::U32).unwrap(), 16909060.0);
        assert_eq!(Binary::<true>::new(&be, 0).read(Scalar::U32).unwrap(), 16909060.0);
        let mut short = Binary::<false>::new(&[1, 2], 100);
        assert!(matches!(short.read(Scalar::F32), Err(Fail::Eof { needed: 4 })));
        assert!(short.error(Path::new("x"), String::new()).to_string().contains("byte 100"));
    }
}
