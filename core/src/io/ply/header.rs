//! The PLY header: its grammar (format, elements, properties, comments), the scalar type names
//! and their aliases, and the size checks that stop a lying header before anything is allocated.

use std::path::Path;

use super::PlyFormat;
use crate::io::IoError;

/// A PLY scalar type. Every name of the specification and its sized alias is accepted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    /// The type a header name denotes (`char`/`int8`, `uchar`/`uint8`, ...).
    pub(crate) fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// Bytes per value in a binary body.
    #[inline]
    pub(crate) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// True for the integer types, the only ones allowed as list counts.
    pub(crate) fn is_integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F64)
    }
}

/// The shape of one property: a single value or a counted list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

impl Kind {
    /// Bytes of the smallest binary instance (a list may be empty, its count is always there).
    pub(crate) fn min_size(self) -> usize {
        match self {
            Self::Scalar(s) => s.size(),
            Self::List { count, .. } => count.size(),
        }
    }
}

/// One `property` line.
#[derive(Clone, Debug)]
pub(crate) struct Property {
    pub name: String,
    pub kind: Kind,
}

/// One `element` line with the properties that follow it.
#[derive(Clone, Debug)]
pub(crate) struct Element {
    pub name: String,
    pub count: u64,
    pub props: Vec<Property>,
}

impl Element {
    /// The smallest number of body bytes one instance can occupy: in binary every scalar and list
    /// count is present (lists may be empty); in ascii every scalar and list count is at least one
    /// character followed by one separator.
    fn min_bytes(&self, format: PlyFormat) -> u64 {
        self.props
            .iter()
            .map(|p| match format {
                PlyFormat::Ascii => 2,
                _ => p.kind.min_size() as u64,
            })
            .sum()
    }

    /// The index of the property called `name`, if any.
    pub(crate) fn find(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }
}

/// A parsed header.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub format: PlyFormat,
    pub elements: Vec<Element>,
    /// `comment` lines other than `TextureFile`, without the keyword.
    pub comments: Vec<String>,
    /// `obj_info` lines, without the keyword.
    pub obj_info: Vec<String>,
    /// `comment TextureFile <name>` names, in order (MeshLab's sheet list).
    pub texture_files: Vec<String>,
    /// Byte offset of the first body byte.
    pub body_offset: usize,
    /// Number of header lines, so ascii body lines can be numbered like the file's.
    pub lines: u64,
}

/// Parses the header at the start of `data` and checks the declared element counts against the
/// body length, so a header claiming billions of elements fails here, before any allocation.
pub(crate) fn parse(path: &Path, data: &[u8]) -> Result<Header, IoError> {
    let mut pos = 0usize;
    let mut line_no = 0u64;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut comments = Vec::new();
    let mut obj_info = Vec::new();
    let mut texture_files = Vec::new();

    loop {
        if pos >= data.len() {
            return Err(IoError::line(
                path,
                line_no.max(1),
                "the header ends without an `end_header` line",
            ));
        }
        let end = data[pos..].iter().position(|&b| b == b'\n').map_or(data.len(), |i| pos + i);
        let raw = &data[pos..end];
        pos = (end + 1).min(data.len());
        line_no += 1;
        // Header lines are ASCII by the specification; comments may carry file names in other
        // encodings, which are kept lossily rather than refused.
        let text = String::from_utf8_lossy(raw);
        let line = text.trim_end_matches('\r');

        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(IoError::line(path, 1, "not a PLY file: the first line must be `ply`"));
            }
            continue;
        }
        let trimmed = line.trim_start();
        let (keyword, rest) = match trimmed.find(|c: char| c.is_ascii_whitespace()) {
            Some(i) => (&trimmed[..i], &trimmed[i..]),
            None => (trimmed, ""),
        };
        match keyword {
            "" => {}
            "comment" => match texture_file(rest) {
                Some(name) => texture_files.push(name.to_string()),
                None => comments.push(rest.trim().to_string()),
            },
            "obj_info" => obj_info.push(rest.trim().to_string()),
            "format" => {
                let f = parse_format(path, line_no, rest)?;
                if format.is_some() {
                    return Err(IoError::line(path, line_no, "a second `format` line"));
                }
                format = Some(f);
            }
            "element" => {
                let element = parse_element(path, line_no, rest)?;
                if elements.iter().any(|e| e.name == element.name) {
                    return Err(IoError::line(
                        path,
                        line_no,
                        format!("element `{}` is declared twice", element.name),
                    ));
                }
                elements.push(element);
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(IoError::line(path, line_no, "`property` before any `element`"));
                };
                let property = parse_property(path, line_no, rest)?;
                if element.find(&property.name).is_some() {
                    return Err(IoError::line(
                        path,
                        line_no,
                        format!(
                            "element `{}`: property `{}` is declared twice",
                            element.name, property.name
                        ),
                    ));
                }
                element.props.push(property);
            }
            "end_header" => break,
            other => {
                return Err(IoError::line(
                    path,
                    line_no,
                    format!("unknown header keyword `{other}` (is `end_header` missing?)"),
                ));
            }
        }
    }

    let Some(format) = format else {
        return Err(IoError::invalid(path, "the header has no `format` line"));
    };
    let header = Header {
        format,
        elements,
        comments,
        obj_info,
        texture_files,
        body_offset: pos,
        lines: line_no,
    };
    check_sizes(path, &header, (data.len() - pos) as u64)?;
    Ok(header)
}

/// The file name of a `comment TextureFile <name>` line (`rest` is the line after `comment`),
/// or `None` for any other comment.
fn texture_file(rest: &str) -> Option<&str> {
    let body = rest.trim();
    let (first, name) = match body.find(|c: char| c.is_ascii_whitespace()) {
        Some(i) => (&body[..i], body[i..].trim()),
        None => (body, ""),
    };
    (first.eq_ignore_ascii_case("TextureFile") && !name.is_empty()).then_some(name)
}

/// The body format named on a `format` line (`rest` is the line after the keyword).
fn parse_format(path: &Path, line_no: u64, rest: &str) -> Result<PlyFormat, IoError> {
    let mut it = rest.split_ascii_whitespace();
    match it.next() {
        Some("ascii") => Ok(PlyFormat::Ascii),
        Some("binary_little_endian") => Ok(PlyFormat::BinaryLittleEndian),
        Some("binary_big_endian") => Ok(PlyFormat::BinaryBigEndian),
        other => Err(IoError::line(
            path,
            line_no,
            format!(
                "unknown PLY format `{}` (expected ascii, binary_little_endian or \
                 binary_big_endian)",
                other.unwrap_or("")
            ),
        )),
    }
}

/// The element declared on an `element <name> <count>` line, without properties yet.
fn parse_element(path: &Path, line_no: u64, rest: &str) -> Result<Element, IoError> {
    let mut it = rest.split_ascii_whitespace();
    let (Some(name), Some(count), None) = (it.next(), it.next(), it.next()) else {
        return Err(IoError::line(path, line_no, "expected `element <name> <count>`"));
    };
    let count: u64 = count.parse().map_err(|_| {
        IoError::line(
            path,
            line_no,
            format!("element `{name}`: count `{count}` is not a non-negative integer"),
        )
    })?;
    Ok(Element { name: name.to_string(), count, props: Vec::new() })
}

/// The property declared on a `property <type> <name>` or
/// `property list <count type> <item type> <name>` line.
fn parse_property(path: &Path, line_no: u64, rest: &str) -> Result<Property, IoError> {
    let words: Vec<&str> = rest.split_ascii_whitespace().collect();
    let bad_type = |t: &str| IoError::line(path, line_no, format!("unknown property type `{t}`"));
    let (kind, name) = match words.as_slice() {
        ["list", count, item, name] => {
            let count = Scalar::from_name(count).ok_or_else(|| bad_type(count))?;
            let item = Scalar::from_name(item).ok_or_else(|| bad_type(item))?;
            if !count.is_integer() {
                return Err(IoError::line(
                    path,
                    line_no,
                    format!("list `{name}`: the count type must be an integer type"),
                ));
            }
            (Kind::List { count, item }, *name)
        }
        [ty, name] if *ty != "list" => {
            (Kind::Scalar(Scalar::from_name(ty).ok_or_else(|| bad_type(ty))?), *name)
        }
        _ => {
            return Err(IoError::line(
                path,
                line_no,
                "expected `property <type> <name>` or \
                 `property list <count type> <item type> <name>`",
            ));
        }
    };
    Ok(Property { name: name.to_string(), kind })
}

/// Refuses a header whose elements cannot fit in the body, even at their smallest.
fn check_sizes(path: &Path, header: &Header, body_len: u64) -> Result<(), IoError> {
    // In ascii the last value needs no trailing separator, hence one byte of slack; binary
    // bodies must hold every byte.
    let slack = u64::from(header.format == PlyFormat::Ascii);
    let mut needed: u64 = 0;
    for e in &header.elements {
        let per = e.min_bytes(header.format);
        let total = per.checked_mul(e.count).and_then(|t| needed.checked_add(t));
        match total {
            Some(t) if t <= body_len.saturating_add(slack) => needed = t,
            _ => {
                return Err(IoError::invalid(
                    path,
                    format!(
                        "the header declares {} `{}` elements needing at least {} bytes each, \
                         but the body after the header is only {body_len} bytes long",
                        e.count, e.name, per
                    ),
                ));
            }
        }
    }
    Ok(())
}
