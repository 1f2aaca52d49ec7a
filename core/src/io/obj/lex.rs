//! Byte-level lexing shared by the OBJ and MTL readers: logical lines (with `\` continuation and
//! CRLF), keywords, whitespace-separated tokens, numbers and indices.
//!
//! Everything here works on raw bytes of the memory-mapped file and allocates nothing, except a
//! reused scratch buffer for the rare lines joined by a trailing backslash.

/// True for the bytes OBJ treats as blanks between tokens. `\r` is included so CRLF files need
/// no special case: the carriage return is just trailing whitespace.
#[inline]
pub(super) fn is_blank(b: u8) -> bool {
    // Space, or one of \t \n (never inside a line) 0x0b 0x0c \r: one compare and one range.
    b == b' ' || (b'\t'..=b'\r').contains(&b)
}

/// Strips a trailing `\r` (CRLF files) from a physical line.
#[inline]
fn strip_cr(line: &[u8]) -> &[u8] {
    match line.last() {
        Some(b'\r') => &line[..line.len() - 1],
        _ => line,
    }
}

/// If the physical line ends with a continuation backslash, the line without it.
#[inline]
fn continued(line: &[u8]) -> Option<&[u8]> {
    let l = strip_cr(line);
    match l.last() {
        Some(b'\\') => Some(&l[..l.len() - 1]),
        _ => None,
    }
}

/// True when the physical line ending just before `end` (the index of its `\n`) continues on the
/// next line. Used to keep chunk boundaries off continued lines.
pub(super) fn continues_at(buf: &[u8], newline: usize) -> bool {
    let start = memchr::memrchr(b'\n', &buf[..newline]).map_or(0, |i| i + 1);
    continued(&buf[start..newline]).is_some()
}

/// Calls `f(line, line_no)` for every logical line of `buf`, where `line_no` is the number of
/// the line's first physical line (the first line of `buf` is `first_line`). Lines joined with a
/// trailing `\` are handed over as one line, the backslash and line break replaced by a blank.
/// Stops at the first error of `f`. Returns the number of physical lines in `buf` (a last line
/// without a line break counts).
pub(super) fn for_each_line<E>(
    buf: &[u8],
    first_line: u64,
    mut f: impl FnMut(&[u8], u64) -> Result<(), E>,
) -> Result<u64, E> {
    let mut pos = 0usize;
    let mut line_no = first_line;
    let mut scratch: Vec<u8> = Vec::new();
    while pos < buf.len() {
        let end = memchr::memchr(b'\n', &buf[pos..]).map_or(buf.len(), |i| pos + i);
        let line = &buf[pos..end];
        let start_no = line_no;
        line_no += 1;
        pos = end + 1;
        match continued(line) {
            None => f(line, start_no)?,
            Some(head) => {
                // Rare slow path: join the physical lines into the scratch buffer.
                scratch.clear();
                scratch.extend_from_slice(head);
                scratch.push(b' ');
                while pos < buf.len() {
                    let end = memchr::memchr(b'\n', &buf[pos..]).map_or(buf.len(), |i| pos + i);
                    let next = &buf[pos..end];
                    line_no += 1;
                    pos = end + 1;
                    match continued(next) {
                        Some(h) => {
                            scratch.extend_from_slice(h);
                            scratch.push(b' ');
                        }
                        None => {
                            scratch.extend_from_slice(next);
                            break;
                        }
                    }
                }
                f(&scratch, start_no)?;
            }
        }
    }
    Ok(line_no - first_line)
}

/// Splits a line into its keyword and the rest (which starts at the blank after the keyword).
/// An empty or blank line gives an empty keyword.
#[inline]
pub(super) fn split_keyword(line: &[u8]) -> (&[u8], &[u8]) {
    let mut i = 0;
    while i < line.len() && is_blank(line[i]) {
        i += 1;
    }
    let start = i;
    while i < line.len() && !is_blank(line[i]) {
        i += 1;
    }
    (&line[start..i], &line[i..])
}

/// The rest of a line as text without surrounding blanks (names may contain inner spaces).
pub(super) fn rest_text(rest: &[u8]) -> String {
    String::from_utf8_lossy(trim(rest)).into_owned()
}

/// `bytes` without leading and trailing blanks.
pub(super) fn trim(bytes: &[u8]) -> &[u8] {
    let start = bytes.iter().position(|&b| !is_blank(b)).unwrap_or(bytes.len());
    let end = bytes.iter().rposition(|&b| !is_blank(b)).map_or(start, |i| i + 1);
    &bytes[start..end.max(start)]
}

/// The number of blank-separated tokens of a statement's arguments; a `#` at the start of a
/// token begins a trailing comment. Pass 1 counts face corners with it, and pass 2's tokenizer
/// ([`at_token`]) splits exactly the same way.
#[inline]
pub(super) fn count_tokens(bytes: &[u8]) -> u64 {
    // Branch-free count of token starts (a non-blank after a blank), which the compiler can
    // vectorize; token starts with `#` are counted alongside so comments take the slow path.
    // Byte-wide counters over blocks of at most 255 bytes cannot overflow and keep 16 or 32
    // bytes per vector step.
    let mut starts = 0u64;
    let mut hashes = 0u64;
    let mut prev_blank = true;
    for block in bytes.chunks(255) {
        let (mut s, mut h) = (0u8, 0u8);
        for &c in block {
            let blank = is_blank(c);
            s += u8::from(prev_blank & !blank);
            h += u8::from(prev_blank & (c == b'#'));
            prev_blank = blank;
        }
        starts += u64::from(s);
        hashes += u64::from(h);
    }
    if hashes == 0 {
        return starts;
    }
    let mut n = 0;
    let mut in_token = false;
    for &c in bytes {
        if is_blank(c) {
            in_token = false;
        } else if !in_token {
            if c == b'#' {
                break;
            }
            n += 1;
            in_token = true;
        }
    }
    n
}

/// The token starting at `start` (up to the next blank), for error messages.
pub(super) fn token_at(bytes: &[u8], start: usize) -> &[u8] {
    let rest = bytes.get(start..).unwrap_or_default();
    let end = rest.iter().position(|&c| is_blank(c)).unwrap_or(rest.len());
    &rest[..end]
}

/// Skips blanks from `*pos`; true when a token starts there (not the end, not a comment).
#[inline]
pub(super) fn at_token(bytes: &[u8], pos: &mut usize) -> bool {
    while *pos < bytes.len() && is_blank(bytes[*pos]) {
        *pos += 1;
    }
    *pos < bytes.len() && bytes[*pos] != b'#'
}

/// Parses the number token starting at `*pos` (after [`at_token`]) in place and moves past it.
/// `Err(())` when the token is not exactly one number (`nan`, `inf` and exponents are numbers).
#[inline]
pub(super) fn number_at<T: fast_float2::FastFloat>(bytes: &[u8], pos: &mut usize) -> Result<T, ()> {
    let (x, n) = fast_float2::parse_partial::<T, _>(&bytes[*pos..]).map_err(|_| ())?;
    *pos += n;
    if *pos < bytes.len() && !is_blank(bytes[*pos]) {
        return Err(());
    }
    Ok(x)
}

/// Reads an OBJ index (optional sign, 1 to 18 digits, so it always fits an `i64`) starting at
/// `*pos` and moves past it.
#[inline]
pub(super) fn index_at(bytes: &[u8], pos: &mut usize) -> Option<i64> {
    let mut i = *pos;
    let neg = match bytes.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let start = i;
    let mut v: i64 = 0;
    while let Some(&d) = bytes.get(i) {
        if !d.is_ascii_digit() {
            break;
        }
        if i - start == 18 {
            // A 19th digit could overflow; no file holds that many elements anyway.
            return None;
        }
        v = v * 10 + i64::from(d - b'0');
        i += 1;
    }
    if i == start {
        return None;
    }
    *pos = i;
    Some(if neg { -v } else { v })
}

/// Parses a whole token as an `f64` (accepts `nan`, `inf`, exponents).
#[inline]
pub(super) fn parse_f64(tok: &[u8]) -> Option<f64> {
    fast_float2::parse::<f64, _>(tok).ok()
}

/// A token quoted for an error message, shortened so a garbage line cannot flood the message.
pub(super) fn quote(tok: &[u8]) -> String {
    const MAX: usize = 40;
    let s = String::from_utf8_lossy(&tok[..tok.len().min(MAX)]);
    if tok.len() > MAX { format!("'{s}...'") } else { format!("'{s}'") }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(buf: &[u8]) -> Vec<(String, u64)> {
        let mut out = Vec::new();
        let n = for_each_line::<()>(buf, 1, |l, no| {
            out.push((String::from_utf8_lossy(l).into_owned(), no));
            Ok(())
        })
        .unwrap();
        out.push((String::new(), n));
        out
    }

    #[test]
    fn logical_lines_join_continuations_and_count_physical_lines() {
        let got = lines(b"a\r\nf 1 \\\n 2 \\\r\n3\nlast");
        assert_eq!(got[0], ("a\r".to_string(), 1));
        assert_eq!(got[1], ("f 1   2  3".to_string(), 2));
        assert_eq!(got[2], ("last".to_string(), 5));
        assert_eq!(got[3].1, 5);
        assert_eq!(lines(b"x\n").last().unwrap().1, 1);
    }

    #[test]
    fn tokens_numbers_and_indices() {
        assert_eq!(parse_f64(b"1e3"), Some(1000.0));
        assert!(parse_f64(b"1.5e").is_none());
        assert!(parse_f64(b"NaN").is_some_and(f64::is_nan));
        assert_eq!(count_tokens(b" 1 2/3\t4 #5 6"), 3);
        let mut p = 0;
        assert_eq!(index_at(b"-12/3", &mut p), Some(-12));
        assert_eq!(p, 3);
        let mut p = 0;
        assert_eq!(index_at(b"1234567890123456789", &mut p), None);
        let mut p = 1;
        assert!(at_token(b"  2.5e1 x", &mut p));
        assert_eq!(number_at::<f64>(b"  2.5e1 x", &mut p), Ok(25.0));
        assert!(at_token(b"  2.5e1 x", &mut p));
        assert_eq!(number_at::<f64>(b"  2.5e1 x", &mut p), Err(()));
        assert_eq!(token_at(b"a bc d", 2), b"bc");
        assert_eq!(split_keyword(b"  vt 1 2"), (&b"vt"[..], &b" 1 2"[..]));
        assert_eq!(trim(b" \ta b\r"), b"a b");
    }
}
