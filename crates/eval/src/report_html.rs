//! Self-contained HTML reports: one page, every image embedded as a base64 `data:` URI, no
//! network, so a report can be mailed, archived or opened offline and still show its plots
//! and maps (`report.html` of every run). The only script a page may hold is the few lines
//! that zoom its maps ([`crate::report_svg::ZOOM_SCRIPT`]).
//!
//! ```
//! use slamkit_eval::report_html::HtmlReport;
//!
//! let mut page = HtmlReport::new("slamkit demo");
//! page.heading(2, "Position error");
//! page.table(&["method", "mean [m]"], &[vec!["ICP".to_owned(), "0.042".to_owned()]]);
//! let html = page.finish();
//! assert!(html.starts_with("<!DOCTYPE html>\n") && html.ends_with("</html>\n"));
//! assert!(html.contains("<tr><td>ICP</td><td>0.042</td></tr>\n"));
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A picture in a [`HtmlReport::gallery`].
#[derive(Debug, Clone)]
pub struct Figure {
    /// Alternative text.
    pub alt: String,
    /// The PNG file.
    pub png: PathBuf,
    /// Caption under the picture (HTML).
    pub caption: String,
}

/// A page being built, top to bottom; text arguments are HTML, inserted as given.
#[derive(Debug, Clone)]
pub struct HtmlReport {
    html: String,
}

/// Why a report could not be built or written.
#[derive(Debug, thiserror::Error)]
#[error("{action} {path}")]
pub struct ReportError {
    /// `reading` (an image) or `writing` (the page).
    pub action: &'static str,
    /// The file.
    pub path: PathBuf,
    /// The operating system's error.
    #[source]
    pub source: std::io::Error,
}

impl HtmlReport {
    /// A page whose title and first heading are `title`.
    pub fn new(title: &str) -> Self {
        let mut html = String::new();
        let _ = write!(
            html,
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <title>{title}</title>\n<style>\n\
             body {{ font-family: sans-serif; margin: 2em; color: #222; }}\n\
             table {{ border-collapse: collapse; }}\n\
             td, th {{ border: 1px solid #aaa; padding: 0.3em 0.8em; text-align: right; }}\n\
             img {{ border: 1px solid #ccc; image-rendering: pixelated; }}\n\
             .plot {{ max-width: 100%; }}\n\
             .gallery {{ display: flex; flex-wrap: wrap; gap: 1em; }}\n\
             figure {{ margin: 0; }} figure img {{ width: 240px; }}\n\
             </style>\n</head>\n<body>\n<h1>{title}</h1>\n"
        );
        Self { html }
    }

    /// A paragraph.
    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.html, "<p>{text}</p>");
    }

    /// A heading of `level` (2 for a section, 3 below it).
    pub fn heading(&mut self, level: u8, text: &str) {
        let _ = writeln!(self.html, "<h{level}>{text}</h{level}>");
    }

    /// A table with a header row.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.html.push_str("<table>\n<tr>");
        for h in header {
            let _ = write!(self.html, "<th>{h}</th>");
        }
        self.html.push_str("</tr>\n");
        for row in rows {
            self.html.push_str("<tr>");
            for cell in row {
                let _ = write!(self.html, "<td>{cell}</td>");
            }
            self.html.push_str("</tr>\n");
        }
        self.html.push_str("</table>\n");
    }

    /// HTML inserted as given: a figure of [`crate::report_svg`], or its zoom script.
    pub fn raw(&mut self, html: &str) {
        self.html.push_str(html);
    }

    /// A PNG image at its own size, or as wide as the page at most when `plot` (for figures
    /// wider than a screen).
    pub fn image(&mut self, alt: &str, png: &Path, plot: bool) -> Result<(), ReportError> {
        let class = if plot { "class=\"plot\" " } else { "" };
        let src = data_uri(png)?;
        let _ = writeln!(self.html, "<img {class}alt=\"{alt}\" src=\"{src}\">");
        Ok(())
    }

    /// Small pictures side by side, each with its caption.
    pub fn gallery(&mut self, figures: &[Figure]) -> Result<(), ReportError> {
        self.html.push_str("<div class=\"gallery\">\n");
        for f in figures {
            let _ = writeln!(
                self.html,
                "<figure><img alt=\"{}\" src=\"{}\"><figcaption>{}</figcaption></figure>",
                f.alt,
                data_uri(&f.png)?,
                f.caption
            );
        }
        self.html.push_str("</div>\n");
        Ok(())
    }

    /// The finished page.
    pub fn finish(mut self) -> String {
        self.html.push_str("</body>\n</html>\n");
        self.html
    }

    /// Finishes the page and writes it to `path`.
    pub fn write(self, path: &Path) -> Result<(), ReportError> {
        std::fs::write(path, self.finish()).map_err(|source| ReportError {
            action: "writing",
            path: path.to_path_buf(),
            source,
        })
    }
}

/// A PNG file as a `data:` URI.
fn data_uri(png: &Path) -> Result<String, ReportError> {
    let bytes = std::fs::read(png).map_err(|source| ReportError {
        action: "reading",
        path: png.to_path_buf(),
        source,
    })?;
    Ok(format!("data:image/png;base64,{}", base64(&bytes)))
}

/// Standard base64 (RFC 4648, with padding): how HTML embeds images and JSON carries bytes
/// (Foxglove's JSON schemas, `slamkit_slam::record`).
///
/// ```
/// assert_eq!(slamkit_eval::report_html::base64(b"foobar"), "Zm9vYmFy");
/// ```
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }

    #[test]
    fn images_are_embedded_and_a_missing_one_names_its_file() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("a.png");
        std::fs::write(&png, b"foo").unwrap();
        let mut page = HtmlReport::new("t");
        page.image("a", &png, true).unwrap();
        let figure = Figure {
            alt: "b".into(),
            png: png.clone(),
            caption: "c".into(),
        };
        page.gallery(&[figure]).unwrap();
        let html = page.finish();
        assert!(
            html.contains("<img class=\"plot\" alt=\"a\" src=\"data:image/png;base64,Zm9v\">\n")
        );
        assert!(html.contains("<figure><img alt=\"b\" src=\"data:image/png;base64,Zm9v\"><figcaption>c</figcaption></figure>\n"));
        let missing = dir.path().join("missing.png");
        let err = HtmlReport::new("t")
            .image("m", &missing, false)
            .unwrap_err();
        assert!(err.to_string().contains("missing.png"), "{err}");
    }
}
