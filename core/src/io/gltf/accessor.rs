//! Typed views of glTF accessors over the loaded buffers, parsed from the JSON by hand:
//! componentType, type, normalized, count, byteOffset and the bufferView's byteStride, with every
//! byte range checked against its bufferView and buffer before anything is read.

use std::path::Path;

use serde_json::Value;

use super::source::BufferData;
use crate::io::IoError;

/// A glTF componentType.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Comp {
    I8,
    U8,
    I16,
    U16,
    U32,
    F32,
}

impl Comp {
    pub(super) fn from_code(code: u64) -> Option<Self> {
        Some(match code {
            5120 => Self::I8,
            5121 => Self::U8,
            5122 => Self::I16,
            5123 => Self::U16,
            5125 => Self::U32,
            5126 => Self::F32,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::U32 | Self::F32 => 4,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Self::I8 => "BYTE",
            Self::U8 => "UNSIGNED_BYTE",
            Self::I16 => "SHORT",
            Self::U16 => "UNSIGNED_SHORT",
            Self::U32 => "UNSIGNED_INT",
            Self::F32 => "FLOAT",
        }
    }
}

/// Number of components of an accessor `type`.
pub(super) fn type_components(t: &str) -> Option<usize> {
    Some(match t {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// Reads an optional non-negative integer member, with a message naming `ctx` when it is not one.
pub(super) fn opt_usize(v: &Value, key: &str, ctx: &str) -> Result<Option<usize>, String> {
    match v.get(key) {
        None => Ok(None),
        Some(x) => x
            .as_u64()
            .and_then(|u| usize::try_from(u).ok())
            .map(Some)
            .ok_or_else(|| format!("{ctx}.{key} is not a non-negative integer")),
    }
}

/// One element array of the JSON document by index, with a clear error when out of range.
pub(super) fn item<'v>(json: &'v Value, array: &str, i: usize) -> Result<&'v Value, String> {
    let list = json.get(array).and_then(Value::as_array);
    let n = list.map_or(0, Vec::len);
    list.and_then(|l| l.get(i))
        .ok_or_else(|| format!("{array}[{i}] does not exist (the file has {n})"))
}

/// A validated accessor: element `i`, component `c` lives at `data[i * stride + c * size]`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Accessor<'a> {
    pub index: usize,
    pub comp: Comp,
    pub ncomp: usize,
    pub normalized: bool,
    pub count: usize,
    pub stride: usize,
    /// The bytes from element 0 to the end of the last element; `None` when the accessor has no
    /// bufferView (all zeros by the specification).
    data: Option<&'a [u8]>,
}

impl<'a> Accessor<'a> {
    /// Parses and bounds-checks accessor `index`.
    pub(super) fn new(
        path: &Path,
        json: &Value,
        buffers: &'a [BufferData],
        index: usize,
    ) -> Result<Self, IoError> {
        let err = |m: String| IoError::invalid(path, m);
        let a = item(json, "accessors", index).map_err(err)?;
        let ctx = format!("accessors[{index}]");
        if a.get("sparse").is_some() {
            return Err(IoError::unsupported(
                path,
                format!(
                    "{ctx} is a sparse accessor; densify it first (e.g. `gltf-transform sparse --ratio 0 IN OUT`)"
                ),
            ));
        }
        let code = a
            .get("componentType")
            .and_then(Value::as_u64)
            .ok_or_else(|| err(format!("{ctx}: missing or invalid componentType")))?;
        let comp = Comp::from_code(code)
            .ok_or_else(|| err(format!("{ctx}: unknown componentType {code}")))?;
        let ty = a.get("type").and_then(Value::as_str).unwrap_or("");
        let ncomp = type_components(ty)
            .ok_or_else(|| err(format!("{ctx}: unknown or missing type {ty:?}")))?;
        let normalized = a.get("normalized").and_then(Value::as_bool).unwrap_or(false);
        let count = opt_usize(a, "count", &ctx)
            .map_err(err)?
            .ok_or_else(|| err(format!("{ctx}: missing count")))?;
        if count == 0 {
            return Err(err(format!("{ctx}: count is 0")));
        }
        let elem = comp.size() * ncomp;
        let offset = opt_usize(a, "byteOffset", &ctx).map_err(err)?.unwrap_or(0);
        let Some(view) = opt_usize(a, "bufferView", &ctx).map_err(err)? else {
            return Ok(Self { index, comp, ncomp, normalized, count, stride: elem, data: None });
        };
        let bv = item(json, "bufferViews", view).map_err(|m| err(format!("{ctx}: {m}")))?;
        let vctx = format!("bufferViews[{view}]");
        let buffer = opt_usize(bv, "buffer", &vctx)
            .map_err(err)?
            .ok_or_else(|| err(format!("{vctx}: missing buffer")))?;
        let view_off = opt_usize(bv, "byteOffset", &vctx).map_err(err)?.unwrap_or(0) as u64;
        let view_len = opt_usize(bv, "byteLength", &vctx)
            .map_err(err)?
            .ok_or_else(|| err(format!("{vctx}: missing byteLength")))?
            as u64;
        let stride = match opt_usize(bv, "byteStride", &vctx).map_err(err)? {
            Some(s) if s < elem => {
                return Err(err(format!(
                    "{ctx}: {vctx} byteStride {s} is smaller than the {elem}-byte element"
                )));
            }
            Some(s) => s,
            None => elem,
        };
        let data = buffers.get(buffer).ok_or_else(|| {
            err(format!("{vctx}: buffer {buffer} does not exist (the file has {})", buffers.len()))
        })?;
        let data = data.bytes();
        let view_end = view_off.saturating_add(view_len);
        if view_end > data.len() as u64 {
            return Err(err(format!(
                "{vctx}: bytes {view_off}..{view_end} lie outside buffer {buffer} ({} bytes)",
                data.len()
            )));
        }
        // All sums in u64: a lying count cannot overflow or allocate, it only fails this check.
        let need = (count as u64 - 1)
            .checked_mul(stride as u64)
            .and_then(|x| x.checked_add(elem as u64))
            .and_then(|x| x.checked_add(offset as u64))
            .unwrap_or(u64::MAX);
        if need > view_len {
            return Err(err(format!(
                "{ctx}: {count} elements need bytes {offset}..{} of {vctx}, which is only {view_len} bytes long",
                if need == u64::MAX { "overflow".to_string() } else { need.to_string() }
            )));
        }
        let start = (view_off + offset as u64) as usize;
        let end = (view_off + need) as usize;
        Ok(Self { index, comp, ncomp, normalized, count, stride, data: Some(&data[start..end]) })
    }

    /// Size of one element in bytes (without stride padding).
    pub(super) fn elem_size(&self) -> usize {
        self.comp.size() * self.ncomp
    }

    /// The raw bytes of element `i` (`None` for an accessor without bufferView: zeros).
    #[inline]
    pub(super) fn element_bytes(&self, i: usize) -> Option<&'a [u8]> {
        let d = self.data?;
        let s = i * self.stride;
        Some(&d[s..s + self.elem_size()])
    }

    /// Component `c` of element `i` as a number, normalized integers mapped to [0, 1] or [-1, 1].
    /// Callers guarantee `i < count` and `c < ncomp`.
    #[inline]
    pub(super) fn get(&self, i: usize, c: usize) -> f64 {
        let Some(d) = self.data else { return 0.0 };
        let o = i * self.stride + c * self.comp.size();
        let n = self.normalized;
        match self.comp {
            Comp::F32 => f64::from(f32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]])),
            Comp::U32 => f64::from(u32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]])),
            Comp::U8 => {
                let v = f64::from(d[o]);
                if n { v / 255.0 } else { v }
            }
            Comp::I8 => {
                let v = f64::from(d[o] as i8);
                if n { (v / 127.0).max(-1.0) } else { v }
            }
            Comp::U16 => {
                let v = f64::from(u16::from_le_bytes([d[o], d[o + 1]]));
                if n { v / 65535.0 } else { v }
            }
            Comp::I16 => {
                let v = f64::from(i16::from_le_bytes([d[o], d[o + 1]]));
                if n { (v / 32767.0).max(-1.0) } else { v }
            }
        }
    }

    /// Element `i` of an index accessor (unsigned byte, short or int scalar).
    #[inline]
    pub(super) fn index_at(&self, i: usize) -> u32 {
        let Some(d) = self.data else { return 0 };
        let o = i * self.stride;
        match self.comp {
            Comp::U8 => u32::from(d[o]),
            Comp::U16 => u32::from(u16::from_le_bytes([d[o], d[o + 1]])),
            _ => u32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]]),
        }
    }

    /// Checks that the accessor has `ncomp` components and one of the allowed component types
    /// (`(componentType, normalized)` pairs), naming `role` in the error.
    pub(super) fn expect(
        &self,
        path: &Path,
        role: &str,
        ncomp: usize,
        allowed: &[(Comp, bool)],
    ) -> Result<(), IoError> {
        if self.ncomp != ncomp || !allowed.contains(&(self.comp, self.normalized)) {
            let list: Vec<String> = allowed
                .iter()
                .map(|(c, n)| format!("{}{}", if *n { "normalized " } else { "" }, c.name()))
                .collect();
            return Err(IoError::invalid(
                path,
                format!(
                    "accessors[{}] used as {role}: {} component(s) of {}{}, expected {ncomp} of {}",
                    self.index,
                    self.ncomp,
                    if self.normalized { "normalized " } else { "" },
                    self.comp.name(),
                    list.join(" or ")
                ),
            ));
        }
        Ok(())
    }
}
