//! URI helpers for glTF: percent-decoding and encoding of relative file references, `data:` URIs
//! and relative paths from an output directory to a file.

use std::path::Path;

use base64::Engine as _;

/// Decodes `%XX` escapes (RFC 3986). The result must be UTF-8, since glTF URIs name files.
pub(super) fn percent_decode(s: &str) -> Result<String, String> {
    if !s.contains('%') {
        return Ok(s.to_string());
    }
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex =
                bytes.get(i + 1..i + 3).ok_or_else(|| format!("truncated escape in URI {s:?}"))?;
            let hex = std::str::from_utf8(hex).map_err(|_| format!("bad escape in URI {s:?}"))?;
            let v = u8::from_str_radix(hex, 16)
                .map_err(|_| format!("bad escape %{hex} in URI {s:?}"))?;
            out.push(v);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("URI {s:?} does not decode to UTF-8"))
}

/// Percent-encodes a relative path for use as a glTF URI: everything but RFC 3986 unreserved
/// characters and `/` is escaped, so spaces, `#`, `?` and non-ASCII names survive.
pub(super) fn percent_encode(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for &b in s.as_bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~' | b'/') {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// A decoded `data:` URI.
pub(super) struct DataUri {
    pub mime: String,
    pub bytes: Vec<u8>,
}

/// Decodes a `data:[<mime>][;base64],<payload>` URI; `None` when `uri` is not a data URI.
pub(super) fn parse_data_uri(uri: &str) -> Option<Result<DataUri, String>> {
    let rest = uri.strip_prefix("data:")?;
    Some((|| {
        let (head, payload) =
            rest.split_once(',').ok_or_else(|| "data URI without a ',' separator".to_string())?;
        let (mime, base64) = match head.strip_suffix(";base64") {
            Some(m) => (m, true),
            None => (head, false),
        };
        // Parameters such as `;charset=...` are not part of the MIME type proper.
        let mime = mime.split(';').next().unwrap_or("").to_string();
        let bytes = if base64 {
            // Some writers drop the `=` padding; accept both forms.
            let engine = base64::engine::GeneralPurpose::new(
                &base64::alphabet::STANDARD,
                base64::engine::GeneralPurposeConfig::new()
                    .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
            );
            engine.decode(payload.trim()).map_err(|e| format!("bad base64 in data URI: {e}"))?
        } else {
            percent_decode(payload)?.into_bytes()
        };
        Ok(DataUri { mime, bytes })
    })())
}

/// The URI of `target` relative to directory `from_dir` (absolute when they share only the
/// root), percent-encoded, with `/` separators.
pub(super) fn relative_uri(from_dir: &Path, target: &Path) -> String {
    let from = if from_dir.as_os_str().is_empty() { Path::new(".") } else { from_dir };
    percent_encode(&crate::io::paths::texture_reference(target, from).replace('\\', "/"))
}

/// The MIME type glTF expects for an image file, from its extension.
pub(super) fn mime_of_path(p: &Path) -> Option<&'static str> {
    let ext = p.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "png" => Some("image/png"),
        "jpg" | "jpeg" => Some("image/jpeg"),
        "webp" => Some("image/webp"),
        "ktx2" => Some("image/ktx2"),
        _ => None,
    }
}

/// The usual file extension of an image MIME type.
pub(super) fn extension_of_mime(mime: &str) -> &'static str {
    match mime {
        "image/png" => "png",
        "image/jpeg" => "jpg",
        "image/webp" => "webp",
        "image/ktx2" => "ktx2",
        _ => "bin",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_round_trip_and_errors() {
        assert_eq!(percent_decode("my%20file%23.bin").unwrap(), "my file#.bin");
        assert_eq!(percent_encode("my file#é.bin"), "my%20file%23%C3%A9.bin");
        assert_eq!(percent_decode(&percent_encode("a b/ç.png")).unwrap(), "a b/ç.png");
        assert!(percent_decode("bad%2").is_err());
        assert!(percent_decode("bad%zz").is_err());
    }

    #[test]
    fn data_uris() {
        let d = parse_data_uri("data:application/octet-stream;base64,AAEC").unwrap().unwrap();
        assert_eq!(d.mime, "application/octet-stream");
        assert_eq!(d.bytes, vec![0, 1, 2]);
        let d = parse_data_uri("data:image/png;base64,AAECAw").unwrap().unwrap();
        assert_eq!(d.bytes, vec![0, 1, 2, 3], "unpadded base64 is accepted");
        assert!(parse_data_uri("scene.bin").is_none());
        assert!(parse_data_uri("data:;base64,@@@").unwrap().is_err());
    }

    #[test]
    fn relative_uris() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let img = dir.path().join("tex dir").join("a.png");
        assert_eq!(relative_uri(&out, &img), "../tex%20dir/a.png");
        assert_eq!(relative_uri(dir.path(), &img), "tex%20dir/a.png");
    }
}
