//! SVG previews of 2-D results: contours, polylines and points drawn over a box.
//!
//! ## Coordinates
//!
//! A plot maps the box `[x₀, x₁] × [y₀, y₁]` onto an image `W` pixels wide and
//! `H = W (y₁ − y₀) / (x₁ − x₀)` pixels high, with the same scale `s = W / (x₁ − x₀)` on both
//! axes (the aspect ratio is kept) and the **y axis pointing up**:
//!
//! ```text
//! X = s (x − x₀),        Y = s (y₁ − y).
//! ```
//!
//! Pixel coordinates are printed with four decimals (1/10 000 of a pixel, trailing zeros
//! trimmed), which is far below what any viewer resolves. Whatever lies outside the box is
//! clipped by the image's `viewBox`. Stroke widths and point radii are in pixels.
//!
//! ## Output
//!
//! The document starts with `<svg`, has a `<title>` when one is set, a background rectangle
//! (white unless changed), then one group per call in call order: each call of
//! [`SvgPlot::polylines`] is a `<g>` holding one `<path>` per polyline (`M x,y L x,y …`, ending
//! with `Z` when the polyline is closed), each call of [`SvgPlot::points`] a `<g>` of
//! `<circle>`s. The title is also drawn as text in the top-left corner, on top.
//!
//! Nothing a caller passes can inject markup: colours must be `#rgb`, `#rgba`, `#rrggbb`,
//! `#rrggbbaa` or a name of ASCII letters (`steelblue`, `none`) and are otherwise rejected
//! ([`MeshError::InvalidColor`]); title text is escaped (`&`, `<`, `>`, `"`, `'`), and characters
//! XML does not allow (control characters) become `U+FFFD`. Non-finite coordinates and sizes are
//! rejected before anything is drawn, so a failed call leaves the plot unchanged.
//!
//! ```
//! use zeroset_field_core::{Aabb, Grid, field::FnField};
//! use zeroset_mesh::squares::contour_field;
//! use zeroset_mesh::svg::SvgPlot;
//!
//! let circle = FnField::new(|p: &[f64; 2]| p[0].hypot(p[1]) - 0.5, None);
//! let bounds = Aabb::centered_cube(1.0)?;
//! let contour = contour_field(&circle, &Grid::vertex_centered(bounds, [64, 64])?, 0.0)?;
//! let mut plot = SvgPlot::new(bounds, 400)?;
//! plot.title("f = |x| − 0.5")
//!     .polylines(&contour, "#1f77b4", 1.5)?
//!     .points(&[[0.0, 0.0]], "black", 3.0)?;
//! let svg = plot.to_string();
//! assert!(svg.starts_with("<svg"));
//! // plot.write("circle.svg")?; // atomic: a complete file or none
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt::{self, Write as _};
use std::path::Path;

use zeroset_field_core::geometry::{Aabb, Point2};
use zeroset_field_core::io::write_atomic;

use crate::error::{MeshError, Result};
use crate::squares::Polyline;

/// An SVG image of a 2-D box, built up call by call (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct SvgPlot {
    bounds: Aabb<2>,
    width: f64,
    height: f64,
    scale: f64,
    background: Option<String>,
    /// Already escaped.
    title: Option<String>,
    body: String,
}

impl SvgPlot {
    /// An empty plot of `bounds`, `width_px` pixels wide and as high as the box's aspect ratio
    /// makes it, on a white background.
    ///
    /// # Errors
    /// [`MeshError::FlatBounds`] if the box has zero extent on an axis;
    /// [`MeshError::InvalidSize`] if `width_px` is 0.
    pub fn new(bounds: Aabb<2>, width_px: u32) -> Result<Self> {
        let extent = bounds.extent();
        for (axis, &e) in extent.iter().enumerate() {
            if e <= 0.0 {
                return Err(MeshError::FlatBounds {
                    axis,
                    min: bounds.min()[axis],
                    max: bounds.max()[axis],
                });
            }
        }
        if width_px == 0 {
            return Err(MeshError::InvalidSize {
                what: "image width",
                value: 0.0,
            });
        }
        let width = f64::from(width_px);
        let scale = width / extent[0];
        Ok(Self {
            bounds,
            width,
            height: scale * extent[1],
            scale,
            background: Some("white".to_owned()),
            title: None,
            body: String::new(),
        })
    }

    /// The box drawn.
    pub fn bounds(&self) -> Aabb<2> {
        self.bounds
    }

    /// The image width in pixels.
    pub fn width_px(&self) -> f64 {
        self.width
    }

    /// The image height in pixels, `width · (y₁ − y₀) / (x₁ − x₀)`.
    pub fn height_px(&self) -> f64 {
        self.height
    }

    /// The pixel position of a point: `[s (x − x₀), s (y₁ − y)]` (y flipped to point up).
    pub fn to_pixel(&self, p: &Point2) -> [f64; 2] {
        [
            self.scale * (p[0] - self.bounds.min()[0]),
            self.scale * (self.bounds.max()[1] - p[1]),
        ]
    }

    /// Sets the title: an SVG `<title>` and a caption in the top-left corner. The text is
    /// escaped, so any string is safe.
    pub fn title(&mut self, text: &str) -> &mut Self {
        self.title = Some(escape(text));
        self
    }

    /// Sets the background fill, or removes it (`None`: transparent).
    ///
    /// # Errors
    /// [`MeshError::InvalidColor`] for a colour that is not accepted (see the module docs).
    pub fn background(&mut self, fill: Option<&str>) -> Result<&mut Self> {
        self.background = fill.map(check_color).transpose()?.map(str::to_owned);
        Ok(self)
    }

    /// Draws the outline of the box, `width` pixels wide (half of it falls inside the image).
    ///
    /// # Errors
    /// [`MeshError::InvalidColor`], or [`MeshError::InvalidSize`] for a width that is not
    /// finite and positive.
    pub fn frame(&mut self, stroke: &str, width: f64) -> Result<&mut Self> {
        let stroke = check_color(stroke)?;
        check_size("stroke width", width)?;
        let _ = writeln!(
            self.body,
            r#"<rect x="0" y="0" width="{}" height="{}" fill="none" stroke="{stroke}" stroke-width="{}"/>"#,
            num(self.width),
            num(self.height),
            num(width)
        );
        Ok(self)
    }

    /// Draws polylines (a [`Contour`](crate::squares::Contour), a `Vec` or a slice of
    /// [`Polyline`]) with a `stroke` colour and a `width` in pixels: one `<path>` per polyline,
    /// closed with `Z` when the polyline is closed. Empty polylines are skipped.
    ///
    /// # Errors
    /// [`MeshError::InvalidColor`]; [`MeshError::InvalidSize`] for a width that is not finite
    /// and positive; [`MeshError::NonFinitePoint`] naming the first vertex with a NaN or
    /// infinite coordinate. On error nothing is drawn.
    pub fn polylines<L: AsRef<[Polyline]> + ?Sized>(
        &mut self,
        lines: &L,
        stroke: &str,
        width: f64,
    ) -> Result<&mut Self> {
        let lines = lines.as_ref();
        let stroke = check_color(stroke)?;
        check_size("stroke width", width)?;
        for (l, line) in lines.iter().enumerate() {
            check_points(&line.points, Some(l))?;
        }
        let _ = writeln!(
            self.body,
            r#"<g fill="none" stroke="{stroke}" stroke-width="{}" stroke-linejoin="round" stroke-linecap="round">"#,
            num(width)
        );
        for line in lines.iter().filter(|l| !l.points.is_empty()) {
            self.body.push_str("<path d=\"");
            for (k, p) in line.points.iter().enumerate() {
                let [x, y] = self.to_pixel(p);
                let command = match k {
                    0 => "M ",
                    1 => " L ",
                    _ => " ",
                };
                let _ = write!(self.body, "{command}{},{}", num(x), num(y));
            }
            if line.closed {
                self.body.push_str(" Z");
            }
            self.body.push_str("\"/>\n");
        }
        self.body.push_str("</g>\n");
        Ok(self)
    }

    /// Draws points as discs of `radius` pixels filled with `fill`: one `<circle>` each.
    ///
    /// # Errors
    /// [`MeshError::InvalidColor`]; [`MeshError::InvalidSize`] for a radius that is not finite
    /// and positive; [`MeshError::NonFinitePoint`] naming the first point with a NaN or infinite
    /// coordinate. On error nothing is drawn.
    pub fn points(&mut self, points: &[Point2], fill: &str, radius: f64) -> Result<&mut Self> {
        let fill = check_color(fill)?;
        check_size("point radius", radius)?;
        check_points(points, None)?;
        let _ = writeln!(self.body, r#"<g fill="{fill}" stroke="none">"#);
        let r = num(radius);
        for p in points {
            let [x, y] = self.to_pixel(p);
            let _ = writeln!(
                self.body,
                r#"<circle cx="{}" cy="{}" r="{r}"/>"#,
                num(x),
                num(y)
            );
        }
        self.body.push_str("</g>\n");
        Ok(self)
    }

    /// Writes the image to `path` atomically through
    /// [`write_atomic`]: readers see the old file or
    /// the complete new one, never a partial write.
    ///
    /// # Errors
    /// [`MeshError::Field`] with [`zeroset_field_core::Error::Io`] naming the file.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let text = self.to_string();
        write_atomic(path, |w| w.write_all(text.as_bytes()))?;
        Ok(())
    }
}

/// The complete SVG document (`plot.to_string()`).
impl fmt::Display for SvgPlot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (w, h) = (num(self.width), num(self.height));
        writeln!(
            f,
            r#"<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"#
        )?;
        if let Some(title) = &self.title {
            writeln!(f, "<title>{title}</title>")?;
        }
        if let Some(fill) = &self.background {
            writeln!(f, r#"<rect width="100%" height="100%" fill="{fill}"/>"#)?;
        }
        f.write_str(&self.body)?;
        if let Some(title) = &self.title {
            writeln!(
                f,
                r#"<text x="8" y="20" font-family="sans-serif" font-size="14" fill="black">{title}</text>"#
            )?;
        }
        writeln!(f, "</svg>")
    }
}

/// Accepts `#` and 3, 4, 6 or 8 hex digits, or 1 to 32 ASCII letters.
fn check_color(color: &str) -> Result<&str> {
    let ok = match color.strip_prefix('#') {
        Some(hex) => {
            matches!(hex.len(), 3 | 4 | 6 | 8) && hex.bytes().all(|b| b.is_ascii_hexdigit())
        }
        None => (1..=32).contains(&color.len()) && color.bytes().all(|b| b.is_ascii_alphabetic()),
    };
    if ok {
        Ok(color)
    } else {
        Err(MeshError::InvalidColor {
            color: color.to_owned(),
        })
    }
}

fn check_size(what: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(MeshError::InvalidSize { what, value })
    }
}

fn check_points(points: &[Point2], polyline: Option<usize>) -> Result<()> {
    match points.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
        Some(index) => Err(MeshError::NonFinitePoint {
            polyline,
            index,
            point: points[index],
        }),
        None => Ok(()),
    }
}

/// Text made safe for XML content and attributes.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if c.is_control() || c == '\u{FFFE}' || c == '\u{FFFF}' => out.push('\u{FFFD}'),
            c => out.push(c),
        }
    }
    out
}

/// A pixel coordinate: four decimals with trailing zeros trimmed (`2`, `0.5`, `-1.2346`), or
/// exponent notation beyond 10⁹.
fn num(x: f64) -> String {
    if x.abs() >= 1e9 {
        return format!("{x:e}");
    }
    let s = format!("{x:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_owned()
    } else {
        s.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::squares::{Contour, contour_field};
    use zeroset_field_core::field::FnField;
    use zeroset_field_core::{Error, Grid};

    /// A minimal well-formedness check: tags nest and close, attribute quotes pair up, text
    /// holds no raw `<`/`>` and every `&` starts a known entity. Returns the tag names in order.
    fn check_well_formed(s: &str) -> Vec<String> {
        let mut stack: Vec<String> = Vec::new();
        let mut names = Vec::new();
        let mut rest = s;
        while let Some(start) = rest.find('<') {
            check_text(&rest[..start]);
            let end = start + rest[start..].find('>').expect("unclosed tag");
            let tag = &rest[start + 1..end];
            assert!(!tag.contains('<'), "'<' inside tag {tag}");
            assert_eq!(tag.matches('"').count() % 2, 0, "unpaired quote in {tag}");
            if let Some(name) = tag.strip_prefix('/') {
                assert_eq!(stack.pop().as_deref(), Some(name), "mismatched </{name}>");
            } else {
                let name = tag.split_whitespace().next().unwrap().trim_end_matches('/');
                names.push(name.to_owned());
                if !tag.ends_with('/') {
                    stack.push(name.to_owned());
                }
            }
            rest = &rest[end + 1..];
        }
        check_text(rest);
        assert!(stack.is_empty(), "unclosed {stack:?}");
        assert_eq!(names.first().map(String::as_str), Some("svg"));
        names
    }

    fn check_text(text: &str) {
        assert!(!text.contains('>'), "raw '>' in {text:?}");
        for (k, _) in text.match_indices('&') {
            let entity = &text[k..];
            assert!(
                ["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"]
                    .iter()
                    .any(|e| entity.starts_with(e)),
                "bad entity in {text:?}"
            );
        }
    }

    /// The value of attribute `name` in every element `<tag …>`.
    fn attribute(svg: &str, tag: &str, name: &str) -> Vec<String> {
        let open = format!("<{tag} ");
        let key = format!(" {name}=\"");
        svg.match_indices(&open)
            .map(|(k, _)| {
                let element = &svg[k..k + svg[k..].find('>').unwrap()];
                let v = element.find(&key).unwrap() + key.len();
                element[v..v + element[v..].find('"').unwrap()].to_owned()
            })
            .collect()
    }

    fn unit_box() -> Aabb<2> {
        Aabb::new([0.0, 0.0], [2.0, 1.0]).unwrap()
    }

    fn sample_contour() -> Contour {
        let f = FnField::new(
            |p: &Point2| ((p[0] - 1.0).hypot(p[1] - 0.5) - 0.3).min(0.9 + 0.1 * p[0] - p[1]),
            None,
        );
        let grid = Grid::vertex_centered(unit_box(), [61, 31]).unwrap();
        contour_field(&f, &grid, 0.0).unwrap()
    }

    #[test]
    fn output_is_well_formed_with_one_path_per_polyline() {
        let contour = sample_contour();
        assert_eq!((contour.num_closed(), contour.num_open()), (1, 1));
        let mut plot = SvgPlot::new(unit_box(), 300).unwrap();
        plot.title("contour")
            .frame("#333", 1.0)
            .unwrap()
            .polylines(&contour, "#1f77b4", 1.5)
            .unwrap()
            .points(&[[1.0, 0.5], [0.1, 0.1]], "red", 2.0)
            .unwrap();
        let svg = plot.to_string();
        assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
        assert!(svg.ends_with("</svg>\n"));
        let names = check_well_formed(&svg);
        assert_eq!(
            names.iter().filter(|n| *n == "path").count(),
            contour.lines.len()
        );
        assert_eq!(names.iter().filter(|n| *n == "circle").count(), 2);
        let paths = attribute(&svg, "path", "d");
        for (d, line) in paths.iter().zip(&contour.lines) {
            assert!(d.starts_with("M "));
            assert_eq!(d.ends_with(" Z"), line.closed);
            let pairs: Vec<&str> = d
                .split_whitespace()
                .filter(|t| !matches!(*t, "M" | "L" | "Z"))
                .collect();
            assert_eq!(pairs.len(), line.points.len());
            for (pair, p) in pairs.iter().zip(&line.points) {
                let (x, y) = pair.split_once(',').unwrap();
                let px = plot.to_pixel(p);
                assert!((x.parse::<f64>().unwrap() - px[0]).abs() <= 5e-5);
                assert!((y.parse::<f64>().unwrap() - px[1]).abs() <= 5e-5);
            }
        }
    }

    #[test]
    fn the_y_axis_points_up_and_the_aspect_ratio_is_kept() {
        let mut plot = SvgPlot::new(unit_box(), 400).unwrap();
        assert_eq!((plot.width_px(), plot.height_px()), (400.0, 200.0));
        plot.points(&[[0.0, 0.0], [2.0, 1.0], [0.5, 0.25]], "#000", 1.0)
            .unwrap();
        let svg = plot.to_string();
        assert!(svg.contains(r#"width="400" height="200" viewBox="0 0 400 200""#));
        let cx = attribute(&svg, "circle", "cx");
        let cy = attribute(&svg, "circle", "cy");
        assert_eq!(cx, ["0", "400", "100"]);
        assert_eq!(cy, ["200", "0", "150"]);
    }

    #[test]
    fn colours_sizes_and_points_are_validated_and_failures_draw_nothing() {
        let mut plot = SvgPlot::new(unit_box(), 100).unwrap();
        let before = plot.to_string();
        let line = [Polyline {
            points: vec![[0.0, 0.0], [1.0, 1.0]],
            closed: false,
        }];
        for bad in [
            "",
            "#12345",
            "#ggg",
            "red\"/><script>alert(1)</script>",
            "rgb(1,2,3)",
            "a&b",
            "<red>",
        ] {
            assert!(
                matches!(
                    plot.polylines(&line, bad, 1.0),
                    Err(MeshError::InvalidColor { .. })
                ),
                "{bad:?}"
            );
            assert!(plot.points(&[[0.0, 0.0]], bad, 1.0).is_err());
        }
        for good in ["#1f77b4", "#abc", "#abcd", "#1F77B480", "steelblue", "none"] {
            SvgPlot::new(unit_box(), 10)
                .unwrap()
                .polylines(&line, good, 1.0)
                .unwrap();
        }
        for width in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                plot.polylines(&line, "red", width),
                Err(MeshError::InvalidSize { .. })
            ));
            assert!(plot.points(&[[0.0, 0.0]], "red", width).is_err());
        }
        let bad_line = vec![
            line[0].clone(),
            Polyline {
                points: vec![[0.0, 0.0], [f64::NAN, 1.0]],
                closed: true,
            },
        ];
        let err = plot.polylines(&bad_line, "red", 1.0).unwrap_err();
        assert!(matches!(
            err,
            MeshError::NonFinitePoint {
                polyline: Some(1),
                index: 1,
                ..
            }
        ));
        assert!(err.to_string().contains("vertex 1 of polyline 1"), "{err}");
        assert!(matches!(
            plot.points(&[[0.0, 0.0], [0.0, f64::INFINITY]], "red", 1.0),
            Err(MeshError::NonFinitePoint {
                polyline: None,
                index: 1,
                ..
            })
        ));
        assert_eq!(plot.to_string(), before);
        assert!(matches!(
            SvgPlot::new(Aabb::new([0.0, 0.0], [1.0, 0.0]).unwrap(), 100),
            Err(MeshError::FlatBounds { axis: 1, .. })
        ));
        assert!(matches!(
            SvgPlot::new(unit_box(), 0),
            Err(MeshError::InvalidSize { .. })
        ));
    }

    #[test]
    fn title_text_is_escaped() {
        let mut plot = SvgPlot::new(unit_box(), 100).unwrap();
        plot.title("<script>alert(\"x\")</script> & 'y'\u{7}");
        plot.background(None).unwrap();
        let svg = plot.to_string();
        check_well_formed(&svg);
        assert!(!svg.contains("<script"));
        assert!(!svg.contains("<rect"));
        assert!(svg.contains(
            "<title>&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &apos;y&apos;\u{FFFD}</title>"
        ));
    }

    #[test]
    fn numbers_are_short_and_exact_enough() {
        assert_eq!(num(2.0), "2");
        assert_eq!(num(0.5), "0.5");
        assert_eq!(num(-1.234_567), "-1.2346");
        assert_eq!(num(-0.000_01), "0");
        assert_eq!(num(123.000_04), "123");
        assert_eq!(num(3e12), "3e12");
    }

    #[test]
    fn write_is_atomic_and_names_the_file_on_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("contour.svg");
        let mut plot = SvgPlot::new(unit_box(), 200).unwrap();
        plot.polylines(&sample_contour(), "#1f77b4", 1.0).unwrap();
        plot.write(&path).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), plot.to_string());
        // Overwriting leaves exactly one file: no temporary is left behind.
        plot.title("again").write(&path).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), plot.to_string());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let missing = dir.path().join("no-such-dir").join("x.svg");
        match plot.write(&missing) {
            Err(MeshError::Field(Error::Io { path, .. })) => assert_eq!(path, missing),
            other => panic!("{other:?}"),
        }
    }
}
