//! Software-rendered PNG previews: shaded meshes and coloured field slices.
//!
//! - [`render_mesh`] draws a [`TriMesh`] with an orthographic camera fitted to the mesh's
//!   bounds, a z-buffer and Lambert + ambient shading under a light near the viewer. Normals are
//!   the per-vertex normals interpolated across each triangle when the mesh has them, the face
//!   normals otherwise. Back faces (seen from inside: holes, open borders) are drawn darker and
//!   warmer than front faces, so they stand out.
//! - [`render_slice`] draws a [`ScalarField`] on an axis-aligned plane with a diverging colour
//!   map — blue where `f < 0` (inside), white at `0`, red where `f > 0` — scaled by a robust
//!   maximum of `|f|` (the 98th percentile), with the zero contour in black;
//!   [`render_field_2d`] does the same for a 2-D field.
//! - [`Image`] has simple drawing on top (discs, lines, copying one image into another) for
//!   figures such as contours over a field.
//!
//! Both return an [`Image`] (8-bit RGB), written with [`Image::write_png`] (atomically) or
//! encoded with [`Image::to_png_bytes`]. Rendering is single-threaded (the field is sampled with
//! [`ScalarField::values`], whose result does not depend on the thread count) and deterministic:
//! the same input gives the same bytes.
//!
//! ## Camera
//!
//! A [`View`] looks at the mesh from azimuth `φ` (about `+z`, from `+x`) and elevation `θ`
//! (above the `xy` plane): the eye lies along `d = (cos θ cos φ, cos θ sin φ, sin θ)`, the screen
//! right is `r = (−sin φ, cos φ, 0)` and up is `u = d × r`, so `+z` points up on screen for
//! `|θ| < 90°`. The projected bounds fill the image with a 5% margin, aspect ratio kept.
//!
//! [`RenderOptions::up`] picks the world axis drawn upward on screen (default [`Axis::Z`]); the
//! azimuth is then measured about that axis and the elevation above the plane normal to it. The
//! mesh is first moved into the frame `(x', y', z')` where the up axis is `z'`, by a cyclic
//! (handedness-preserving) permutation: up `+x` uses `(y, z, x)`, up `+y` uses `(z, x, y)`, up
//! `+z` leaves the mesh as it is. So a render with up `+y` is exactly the render, with up `+z`,
//! of the mesh with each point `(x, y, z)` replaced by `(z, x, y)`.
//!
//! ## Rasterisation
//!
//! A pixel is covered by a triangle when its centre lies inside or on the triangle's edges
//! (inclusive edge test on barycentric coordinates), and shows the nearest covering triangle;
//! on a depth tie the triangle drawn first (lowest index) wins. Triangles seen exactly edge-on
//! cover nothing.
//!
//! ```
//! use zeroset_field_core::{Aabb, field::FnField};
//! use zeroset_mesh::preview::{RenderOptions, render_mesh, render_slice};
//! use zeroset_mesh::TriMesh;
//!
//! let v = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
//! let image = render_mesh(&TriMesh::new(v, t)?, &RenderOptions::default())?;
//! assert_eq!((image.width(), image.height()), (512, 512));
//! let png = image.to_png_bytes();
//! assert_eq!(&png[1..4], b"PNG");
//!
//! let sphere = FnField::new(|p: &[f64; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5, None);
//! let slice = render_slice(&sphere, Aabb::centered_cube(1.0)?, 2, 0.0, 128)?;
//! assert_eq!((slice.width(), slice.height()), (128, 128));
//! // slice.write_png("slice.png")?; // atomic: a complete file or none
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::borrow::Cow;
use std::path::Path;

use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{cross, dot};
use zeroset_field_core::io::write_atomic;
use zeroset_field_core::{Aabb, Point};

use crate::error::{MeshError, Result};
use crate::trimesh::TriMesh;

/// The largest image width or height accepted, in pixels.
pub const MAX_IMAGE_SIZE: usize = 16384;

/// An 8-bit RGB image, rows top to bottom, pixels left to right.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Image {
    /// An image of one colour.
    ///
    /// # Errors
    /// [`MeshError::ImageSize`] if `width` or `height` is 0 or above [`MAX_IMAGE_SIZE`].
    pub fn filled(width: usize, height: usize, colour: [u8; 3]) -> Result<Self> {
        check_size("width", width)?;
        check_size("height", height)?;
        Ok(Self {
            width,
            height,
            rgb: colour.repeat(width * height),
        })
    }

    /// The width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// The height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixels, 3 bytes (R, G, B) each, rows top to bottom.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// The colour of pixel `(x, y)` (`x` from the left, `y` from the top).
    ///
    /// # Panics
    /// If the pixel is outside the image.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside a {}×{} image",
            self.width,
            self.height
        );
        let i = 3 * (y * self.width + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    fn set(&mut self, x: usize, y: usize, c: [u8; 3]) {
        let i = 3 * (y * self.width + x);
        self.rgb[i..i + 3].copy_from_slice(&c);
    }

    /// Sets pixel `(x, y)`; a pixel outside the image is ignored (drawing clips).
    pub fn set_pixel(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if let (Ok(x), Ok(y)) = (usize::try_from(x), usize::try_from(y))
            && x < self.width
            && y < self.height
        {
            self.set(x, y, colour);
        }
    }

    /// Fills the pixels whose centres lie within `radius` of `centre`, in pixel coordinates
    /// (`x` right, `y` down; pixel `(i, j)` has its centre at `(i + ½, j + ½)`). Clips.
    pub fn fill_disc(&mut self, centre: [f64; 2], radius: f64, colour: [u8; 3]) {
        if !(centre.iter().all(|c| c.is_finite()) && radius.is_finite() && radius > 0.0) {
            return;
        }
        let lo = |c: f64| (c - radius - 0.5).floor().max(-1.0) as i64;
        let hi = |c: f64, n: usize| (c + radius).ceil().min(n as f64) as i64;
        for y in lo(centre[1])..=hi(centre[1], self.height) {
            for x in lo(centre[0])..=hi(centre[0], self.width) {
                let (dx, dy) = (x as f64 + 0.5 - centre[0], y as f64 + 0.5 - centre[1]);
                if dx * dx + dy * dy <= radius * radius {
                    self.set_pixel(x, y, colour);
                }
            }
        }
    }

    /// Draws the segment `a`–`b` (pixel coordinates, as [`Image::fill_disc`]) `width` pixels
    /// wide, with round ends. Clips.
    pub fn draw_line(&mut self, a: [f64; 2], b: [f64; 2], width: f64, colour: [u8; 3]) {
        let length = (b[0] - a[0]).hypot(b[1] - a[1]);
        if !length.is_finite() {
            return;
        }
        let steps = (length * 2.0).ceil().max(1.0) as usize;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
            self.fill_disc(p, width / 2.0, colour);
        }
    }

    /// Copies `other` into this image with its top-left corner at `(x, y)`. Clips.
    pub fn blit(&mut self, other: &Image, x: usize, y: usize) {
        for j in 0..other.height.min(self.height.saturating_sub(y)) {
            let w = other.width.min(self.width.saturating_sub(x));
            let src = 3 * j * other.width;
            let dst = 3 * ((y + j) * self.width + x);
            self.rgb[dst..dst + 3 * w].copy_from_slice(&other.rgb[src..src + 3 * w]);
        }
    }

    /// The image encoded as a PNG file (8-bit RGB, not interlaced).
    pub fn to_png_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        // The size is within 1..=16384 and `rgb` holds exactly width × height pixels (both kept
        // by every constructor), and writing to a `Vec` cannot fail: encoding cannot fail.
        let result = (|| -> std::result::Result<(), png::EncodingError> {
            let mut encoder = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header()?;
            writer.write_image_data(&self.rgb)?;
            writer.finish()
        })();
        if let Err(e) = result {
            unreachable!("encoding a checked image into memory failed: {e}");
        }
        out
    }

    /// Writes the image as a PNG file, atomically: readers of `path` see the old file or the
    /// complete new one.
    ///
    /// # Errors
    /// [`MeshError::Field`] wrapping an I/O error that names `path`.
    pub fn write_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let bytes = self.to_png_bytes();
        write_atomic(path, |w| w.write_all(&bytes))?;
        Ok(())
    }
}

fn check_size(what: &'static str, value: usize) -> Result<()> {
    if value == 0 || value > MAX_IMAGE_SIZE {
        return Err(MeshError::ImageSize {
            what,
            value,
            max: MAX_IMAGE_SIZE,
        });
    }
    Ok(())
}

/// Where the camera looks from, in degrees (see the [module docs](self#camera)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Angle about `+z`, from `+x` towards `+y`.
    pub azimuth: f64,
    /// Angle above the `xy` plane (`90` looks straight down).
    pub elevation: f64,
}

impl Default for View {
    /// A three-quarter view: azimuth 35°, elevation 25°.
    fn default() -> Self {
        Self {
            azimuth: 35.0,
            elevation: 25.0,
        }
    }
}

/// A world axis: [`RenderOptions::up`], the axis drawn upward on screen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Axis {
    /// `+x`.
    X,
    /// `+y` (e.g. the Stanford bunny).
    Y,
    /// `+z` (the default).
    #[default]
    Z,
}

impl Axis {
    /// The coordinate index: 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// Maps a world point into the frame where this axis is the third coordinate, by a cyclic
    /// permutation (see the [module docs](self#camera)).
    fn to_up_frame(self, p: &Point<3>) -> Point<3> {
        let k = self.index();
        [p[(k + 1) % 3], p[(k + 2) % 3], p[k]]
    }
}

/// How [`render_mesh`] draws.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels (1 to [`MAX_IMAGE_SIZE`]).
    pub width: usize,
    /// Image height in pixels (1 to [`MAX_IMAGE_SIZE`]).
    pub height: usize,
    /// Where the camera looks from.
    pub view: View,
    /// The world axis drawn upward on screen: the [`View`]'s azimuth is measured about it and
    /// its elevation above the plane normal to it (see the [module docs](self#camera)).
    pub up: Axis,
    /// The colour where no triangle is drawn.
    pub background: [u8; 3],
    /// The base colour of front faces (back faces get a darker, warmer shade of it).
    pub colour: [u8; 3],
}

impl Default for RenderOptions {
    /// 512 × 512, the default [`View`], `+z` up, a white background, light steel-blue surface.
    fn default() -> Self {
        Self {
            width: 512,
            height: 512,
            view: View::default(),
            up: Axis::Z,
            background: [255, 255, 255],
            colour: [176, 196, 222],
        }
    }
}

fn normalised(a: Point<3>) -> Point<3> {
    let n = dot(&a, &a).sqrt();
    if n > 0.0 && n.is_finite() {
        a.map(|v| v / n)
    } else {
        [0.0; 3]
    }
}

const AMBIENT: f64 = 0.25;
const DIFFUSE: f64 = 0.75;
/// Back faces: intensity factor and the warm tint mixed in.
const BACK_DIM: f64 = 0.55;
const BACK_TINT: [f64; 3] = [200.0, 90.0, 70.0];
const BACK_TINT_WEIGHT: f64 = 0.35;

/// Renders `mesh` into an image (see the [module docs](self)).
///
/// # Errors
/// [`MeshError::ImageSize`] if the width or height is 0 or above [`MAX_IMAGE_SIZE`];
/// [`MeshError::EmptyMesh`] if the mesh has no triangle; [`MeshError::InvalidMesh`] if the view
/// angles are not finite.
pub fn render_mesh(mesh: &TriMesh, opts: &RenderOptions) -> Result<Image> {
    check_size("width", opts.width)?;
    check_size("height", opts.height)?;
    if mesh.is_empty() {
        return Err(MeshError::EmptyMesh);
    }
    let (az, el) = (opts.view.azimuth, opts.view.elevation);
    if !(az.is_finite() && el.is_finite()) {
        return Err(MeshError::InvalidMesh {
            detail: format!("view angles must be finite, got azimuth {az}, elevation {el}"),
        });
    }
    let (sa, ca) = az.to_radians().sin_cos();
    let (se, ce) = el.to_radians().sin_cos();
    let d = [ce * ca, ce * sa, se];
    let r = [-sa, ca, 0.0];
    let u = cross(&d, &r);
    // Light from the viewer, a little up and to the left.
    let light = normalised([0, 1, 2].map(|i| d[i] + 0.35 * u[i] - 0.25 * r[i]));

    // Work in the frame where the up axis is the third coordinate.
    let (verts, normals): (Cow<[Point<3>]>, Cow<[Point<3>]>) = match opts.up {
        Axis::Z => (mesh.vertices().into(), mesh.normals().into()),
        up => (
            mesh.vertices().iter().map(|p| up.to_up_frame(p)).collect(),
            mesh.normals().iter().map(|p| up.to_up_frame(p)).collect(),
        ),
    };
    let (verts, normals) = (&*verts, &*normals);

    // Fit the projection to the vertices the triangles use.
    let mut used = vec![false; verts.len()];
    for tri in mesh.triangles() {
        for &v in tri {
            used[v as usize] = true;
        }
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (p, _) in verts.iter().zip(&used).filter(|(_, u)| **u) {
        let (x, y) = (dot(p, &r), dot(p, &u));
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (w, h) = (opts.width as f64, opts.height as f64);
    let (ex, ey) = (x1 - x0, y1 - y0);
    let sx = if ex > 0.0 {
        0.9 * w / ex
    } else {
        f64::INFINITY
    };
    let sy = if ey > 0.0 {
        0.9 * h / ey
    } else {
        f64::INFINITY
    };
    let mut s = sx.min(sy);
    if !s.is_finite() {
        s = 1.0; // every vertex projects to one point
    }
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let project = |p: &Point<3>| -> [f64; 3] {
        [
            0.5 * w + s * (dot(p, &r) - cx),
            0.5 * h - s * (dot(p, &u) - cy),
            dot(p, &d),
        ]
    };
    let screen: Vec<[f64; 3]> = verts.iter().map(project).collect();

    let base = opts.colour.map(f64::from);
    let back_base: [f64; 3] =
        [0, 1, 2].map(|i| (1.0 - BACK_TINT_WEIGHT) * base[i] + BACK_TINT_WEIGHT * BACK_TINT[i]);
    let mut image = Image::filled(opts.width, opts.height, opts.background)?;
    let mut depth = vec![f64::NEG_INFINITY; opts.width * opts.height];

    for tri in mesh.triangles() {
        let [ia, ib, ic] = tri.map(|v| v as usize);
        let (a, b, c) = (screen[ia], screen[ib], screen[ic]);
        // Twice the signed area in pixel coordinates (y down).
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        let face = normalised(cross(
            &[0, 1, 2].map(|i| verts[ib][i] - verts[ia][i]),
            &[0, 1, 2].map(|i| verts[ic][i] - verts[ia][i]),
        ));
        let front = dot(&face, &d) > 0.0;
        let xmin = a[0].min(b[0]).min(c[0]).floor().max(0.0);
        let xmax = a[0].max(b[0]).max(c[0]).ceil().min(w);
        let ymin = a[1].min(b[1]).min(c[1]).floor().max(0.0);
        let ymax = a[1].max(b[1]).max(c[1]).ceil().min(h);
        if xmin >= xmax || ymin >= ymax {
            continue;
        }
        for py in ymin as usize..ymax as usize {
            let y = py as f64 + 0.5;
            for px in xmin as usize..xmax as usize {
                let x = px as f64 + 0.5;
                // Barycentric weights of a, b, c.
                let wa = ((b[0] - x) * (c[1] - y) - (b[1] - y) * (c[0] - x)) / area;
                let wb = ((c[0] - x) * (a[1] - y) - (c[1] - y) * (a[0] - x)) / area;
                let wc = 1.0 - wa - wb;
                if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                    continue;
                }
                let z = wa * a[2] + wb * b[2] + wc * c[2];
                let k = py * opts.width + px;
                if z <= depth[k] {
                    continue;
                }
                depth[k] = z;
                let n = if normals.is_empty() {
                    face
                } else {
                    let (na, nb, nc) = (normals[ia], normals[ib], normals[ic]);
                    let n = normalised([0, 1, 2].map(|i| wa * na[i] + wb * nb[i] + wc * nc[i]));
                    if n == [0.0; 3] { face } else { n }
                };
                // Shade the side facing the viewer.
                let sign = if front { 1.0 } else { -1.0 };
                let lambert = (sign * dot(&n, &light)).max(0.0);
                let intensity = AMBIENT + DIFFUSE * lambert;
                let colour = if front {
                    base.map(|v| v * intensity)
                } else {
                    back_base.map(|v| v * intensity * BACK_DIM)
                };
                image.set(px, py, colour.map(to_u8));
            }
        }
    }
    Ok(image)
}

fn to_u8(v: f64) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

/// Blue end of the colour map (most negative, inside).
const NEGATIVE: [f64; 3] = [33.0, 102.0, 172.0];
/// Red end of the colour map (most positive, outside).
const POSITIVE: [f64; 3] = [178.0, 24.0, 43.0];
/// The quantile of `|f|` that maps to the ends of the colour map.
const ROBUST_QUANTILE: f64 = 0.98;

/// Renders `field` on the plane `x[axis] = position` across `bounds` (see the
/// [module docs](self)).
///
/// The image shows the other two axes in increasing order, the first to the right and the
/// second up (`axis = 2`: `x` right, `y` up), aspect ratio kept: `pixels` is the longer side.
/// Each pixel shows the field at its centre. A pixel of the zero contour is, for each pair of
/// horizontally or vertically adjacent pixels of different sign (`f < 0` against `f ≥ 0`), the
/// one of the two with the smaller `|f|`: the contour is about one pixel wide and within half a
/// pixel of the true crossing for a smooth field.
///
/// # Errors
/// [`MeshError::ImageSize`] if `pixels` is 0 or above [`MAX_IMAGE_SIZE`];
/// [`MeshError::InvalidSlice`] if `axis > 2`, `position` is not finite, or `bounds` has zero
/// extent on one of the two image axes; [`MeshError::NonFiniteSample`] naming the first pixel
/// (`grid_index` `[column, row]`, rows from the top) where the field is NaN or infinite.
pub fn render_slice<F: ScalarField<3>>(
    field: &F,
    bounds: Aabb<3>,
    axis: usize,
    position: f64,
    pixels: usize,
) -> Result<Image> {
    check_size("slice resolution", pixels)?;
    let invalid = |detail: String| MeshError::InvalidSlice {
        axis,
        position,
        detail,
    };
    if axis > 2 {
        return Err(invalid("the axis must be 0, 1 or 2".into()));
    }
    if !position.is_finite() {
        return Err(invalid("the position must be finite".into()));
    }
    let (ha, va) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let (lo, hi, ext) = (bounds.min(), bounds.max(), bounds.extent());
    for a in [ha, va] {
        if ext[a] <= 0.0 {
            return Err(invalid(format!(
                "the box has zero extent on axis {a} ([{}, {}])",
                lo[a], hi[a]
            )));
        }
    }
    let (width, height) = fit_aspect(pixels, ext[ha], ext[va]);

    let mut points = Vec::with_capacity(width * height);
    for j in 0..height {
        for i in 0..width {
            let mut p = [0.0; 3];
            p[axis] = position;
            p[ha] = lo[ha] + (i as f64 + 0.5) / width as f64 * ext[ha];
            p[va] = hi[va] - (j as f64 + 0.5) / height as f64 * ext[va];
            points.push(p);
        }
    }
    let mut values = vec![0.0; points.len()];
    field.values(&points, &mut values);
    shade(&values, &points, width, height)
}

/// Renders the 2-D `field` across `bounds`, `x` to the right and `y` up, exactly as
/// [`render_slice`] renders a plane of a 3-D field: the same colour map and zero contour,
/// aspect ratio kept, `pixels` the longer side.
///
/// ```
/// use zeroset_field_core::{Aabb, field::FnField};
/// use zeroset_mesh::preview::render_field_2d;
///
/// let circle = FnField::new(|p: &[f64; 2]| p[0].hypot(p[1]) - 0.5, None);
/// let image = render_field_2d(&circle, Aabb::new([-1.0, -1.0], [1.0, 0.0])?, 200)?;
/// assert_eq!((image.width(), image.height()), (200, 100));
/// let [r, _, b] = image.pixel(100, 25); // (0, −0.25): inside, blue
/// assert!(b > r);
/// let [r, _, b] = image.pixel(0, 0); // near the corner (−1, 0): outside, red
/// assert!(r > b);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`MeshError::ImageSize`] if `pixels` is 0 or above [`MAX_IMAGE_SIZE`];
/// [`MeshError::InvalidSlice`] (axis 2, position 0) if `bounds` has zero extent on an axis;
/// [`MeshError::NonFiniteSample`] naming the first pixel where the field is NaN or infinite.
pub fn render_field_2d<F: ScalarField<2> + ?Sized>(
    field: &F,
    bounds: Aabb<2>,
    pixels: usize,
) -> Result<Image> {
    check_size("image resolution", pixels)?;
    let (lo, hi, ext) = (bounds.min(), bounds.max(), bounds.extent());
    for a in 0..2 {
        if ext[a] <= 0.0 {
            return Err(MeshError::InvalidSlice {
                axis: 2,
                position: 0.0,
                detail: format!(
                    "the box has zero extent on axis {a} ([{}, {}])",
                    lo[a], hi[a]
                ),
            });
        }
    }
    let (width, height) = fit_aspect(pixels, ext[0], ext[1]);
    let mut points = Vec::with_capacity(width * height);
    for j in 0..height {
        for i in 0..width {
            points.push([
                lo[0] + (i as f64 + 0.5) / width as f64 * ext[0],
                hi[1] - (j as f64 + 0.5) / height as f64 * ext[1],
            ]);
        }
    }
    let mut values = vec![0.0; points.len()];
    field.values(&points, &mut values);
    shade(&values, &points, width, height)
}

/// The pixel coordinates (as [`Image::fill_disc`]) of the point `p` in an image of
/// `width × height` pixels showing `bounds` as [`render_field_2d`] does (`x` right, `y` up).
pub fn pixel_of(bounds: &Aabb<2>, width: usize, height: usize, p: &Point<2>) -> [f64; 2] {
    let (lo, hi, ext) = (bounds.min(), bounds.max(), bounds.extent());
    [
        (p[0] - lo[0]) / ext[0] * width as f64,
        (hi[1] - p[1]) / ext[1] * height as f64,
    ]
}

/// `(width, height)` with the longer side `pixels` and the aspect ratio `horizontal : vertical`.
fn fit_aspect(pixels: usize, horizontal: f64, vertical: f64) -> (usize, usize) {
    if horizontal >= vertical {
        let h = (pixels as f64 * vertical / horizontal).round().max(1.0) as usize;
        (pixels, h.min(pixels))
    } else {
        let w = (pixels as f64 * horizontal / vertical).round().max(1.0) as usize;
        (w.min(pixels), pixels)
    }
}

/// The colour map and the zero contour of row-major samples (rows top to bottom).
fn shade<const D: usize>(
    values: &[f64],
    points: &[Point<D>],
    width: usize,
    height: usize,
) -> Result<Image> {
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(MeshError::NonFiniteSample {
            index: k,
            grid_index: vec![k % width, k / width],
            position: points[k].to_vec(),
            value: values[k],
        });
    }

    let mut magnitudes: Vec<f64> = values.iter().map(|v| v.abs()).collect();
    let q = ((magnitudes.len() - 1) as f64 * ROBUST_QUANTILE).round() as usize;
    let (_, &mut scale, _) = magnitudes.select_nth_unstable_by(q, f64::total_cmp);
    let scale = if scale > 0.0 { scale } else { 1.0 };

    let mut image = Image::filled(width, height, [255, 255, 255])?;
    for (k, &v) in values.iter().enumerate() {
        let t = (v / scale).clamp(-1.0, 1.0);
        let (end, t) = if t < 0.0 {
            (NEGATIVE, -t)
        } else {
            (POSITIVE, t)
        };
        let c = end.map(|e| 255.0 + t * (e - 255.0));
        image.set(k % width, k / width, c.map(to_u8));
    }
    let mut contour = vec![false; values.len()];
    let mut mark = |p: usize, q: usize| {
        if (values[p] < 0.0) != (values[q] < 0.0) {
            let k = if values[q].abs() < values[p].abs() {
                q
            } else {
                p
            };
            contour[k] = true;
        }
    };
    for j in 0..height {
        for i in 0..width {
            let k = j * width + i;
            if i + 1 < width {
                mark(k, k + 1);
            }
            if j + 1 < height {
                mark(k, k + width);
            }
        }
    }
    for (k, _) in contour.iter().enumerate().filter(|(_, c)| **c) {
        image.set(k % width, k / width, [0, 0, 0]);
    }
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;
    use zeroset_field_core::field::FnField;

    fn cube() -> TriMesh {
        let v = vec![
            [-1.0, -1.0, -1.0],
            [1.0, -1.0, -1.0],
            [1.0, 1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [1.0, 1.0, 1.0],
            [-1.0, 1.0, 1.0],
        ];
        // Counter-clockwise seen from outside.
        let t = vec![
            [0, 3, 2],
            [0, 2, 1],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [2, 3, 7],
            [2, 7, 6],
            [1, 2, 6],
            [1, 6, 5],
            [0, 4, 7],
            [0, 7, 3],
        ];
        TriMesh::new(v, t).unwrap()
    }

    fn tetrahedron() -> TriMesh {
        let v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        TriMesh::new(v, t).unwrap()
    }

    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    }

    fn check_render(mesh: &TriMesh) {
        let opts = RenderOptions {
            width: 160,
            height: 120,
            ..RenderOptions::default()
        };
        let image = render_mesh(mesh, &opts).unwrap();
        let (w, h, rgb) = decode(&image.to_png_bytes());
        assert_eq!((w, h), (160, 120));
        assert_eq!(rgb, image.rgb());
        let bg = opts.background;
        assert_ne!(image.pixel(80, 60), bg, "centre pixel is background");
        for (x, y) in [(0, 0), (159, 0), (0, 119), (159, 119)] {
            assert_eq!(image.pixel(x, y), bg, "corner ({x}, {y}) is drawn");
        }
        // Every drawn pixel is shaded front face for a closed, outward-wound mesh: none is the
        // back-face colour family (red channel dominant over blue).
        for y in 0..120 {
            for x in 0..160 {
                let p = image.pixel(x, y);
                assert!(
                    p == bg || p[2] >= p[0],
                    "back face visible at ({x}, {y}): {p:?}"
                );
            }
        }
    }

    #[test]
    fn renders_tetrahedron_and_cube() {
        check_render(&tetrahedron());
        check_render(&cube());
    }

    #[test]
    fn vertex_normals_are_used() {
        let mesh = cube();
        let normals = mesh.vertices().iter().map(|p| normalised(*p)).collect();
        let smooth = mesh.clone().with_normals(normals).unwrap();
        let opts = RenderOptions::default();
        let flat = render_mesh(&mesh, &opts).unwrap();
        let shaded = render_mesh(&smooth, &opts).unwrap();
        assert_ne!(flat, shaded);
        // Same silhouette.
        let bg = opts.background;
        for (p, q) in flat.rgb().chunks(3).zip(shaded.rgb().chunks(3)) {
            assert_eq!(p == bg, q == bg);
        }
    }

    #[test]
    fn back_faces_are_darker() {
        // The cube without its +z top: looking down, the inside of the bottom is visible.
        let mesh = cube();
        let t: Vec<[u32; 3]> = mesh.triangles()[..2]
            .iter()
            .chain(&mesh.triangles()[4..])
            .copied()
            .collect();
        let open = TriMesh::new(mesh.vertices().to_vec(), t).unwrap();
        let opts = RenderOptions {
            view: View {
                azimuth: 0.0,
                elevation: 90.0,
            },
            ..RenderOptions::default()
        };
        let image = render_mesh(&open, &opts).unwrap();
        let c = image.pixel(256, 256);
        assert!(c[0] > c[2], "expected the warm back-face shade, got {c:?}");
        let closed = render_mesh(&cube(), &opts).unwrap().pixel(256, 256);
        let lum = |p: [u8; 3]| u32::from(p[0]) + u32::from(p[1]) + u32::from(p[2]);
        assert!(lum(c) < lum(closed), "{c:?} vs {closed:?}");
    }

    #[test]
    fn deterministic() {
        let opts = RenderOptions::default();
        let a = render_mesh(&cube(), &opts).unwrap().to_png_bytes();
        let b = render_mesh(&cube(), &opts).unwrap().to_png_bytes();
        assert_eq!(a, b);
        let f = sphere(0.5);
        let bounds = Aabb::centered_cube(1.0).unwrap();
        let s1 = render_slice(&f, bounds, 1, 0.1, 97).unwrap();
        let s2 = render_slice(&f, bounds, 1, 0.1, 97).unwrap();
        assert_eq!(s1.to_png_bytes(), s2.to_png_bytes());
    }

    /// An asymmetric mesh with vertex normals, so that a wrong axis mapping shows.
    fn lopsided() -> TriMesh {
        let mut v = cube().vertices().to_vec();
        for (i, p) in v.iter_mut().enumerate() {
            let t = i as f64;
            *p = [
                p[0] * 1.7 + 0.1 * t,
                p[1] * 0.8 - 0.05 * t,
                p[2] * 1.2 + 0.3,
            ];
        }
        let n: Vec<Point<3>> = v.iter().map(|p| normalised(*p)).collect();
        TriMesh::new(v, cube().triangles().to_vec())
            .unwrap()
            .with_normals(n)
            .unwrap()
    }

    #[test]
    fn up_axis_is_a_cyclic_relabelling() {
        let mesh = lopsided();
        let view = View {
            azimuth: 20.0,
            elevation: 15.0,
        };
        let opts = |up| RenderOptions {
            width: 160,
            height: 120,
            view,
            up,
            ..RenderOptions::default()
        };
        // Up +y: (x, y, z) -> (z, x, y); up +x: (x, y, z) -> (y, z, x).
        type Relabel = fn(&Point<3>) -> Point<3>;
        let cases: [(Axis, Relabel); 2] = [
            (Axis::Y, |p| [p[2], p[0], p[1]]),
            (Axis::X, |p| [p[1], p[2], p[0]]),
        ];
        let z_up = render_mesh(&mesh, &opts(Axis::Z)).unwrap();
        for (up, map) in cases {
            let moved = TriMesh::new(
                mesh.vertices().iter().map(map).collect(),
                mesh.triangles().to_vec(),
            )
            .unwrap()
            .with_normals(mesh.normals().iter().map(map).collect())
            .unwrap();
            let a = render_mesh(&mesh, &opts(up)).unwrap();
            let b = render_mesh(&moved, &opts(Axis::Z)).unwrap();
            assert_eq!(a, b, "{up:?}");
            assert_ne!(a, z_up, "{up:?}");
        }
        // The default is +z up.
        assert_eq!(RenderOptions::default().up, Axis::Z);
        let default_up = RenderOptions {
            up: Axis::default(),
            ..opts(Axis::Z)
        };
        assert_eq!(render_mesh(&mesh, &default_up).unwrap(), z_up);
    }

    fn sphere(r: f64) -> impl ScalarField<3> {
        FnField::new(
            move |p: &[f64; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - r,
            None,
        )
    }

    #[test]
    fn slice_contour_at_radius() {
        let r = 0.5;
        let n = 201;
        let bounds = Aabb::centered_cube(1.0).unwrap();
        for axis in 0..3 {
            let image = render_slice(&sphere(r), bounds, axis, 0.0, n).unwrap();
            assert_eq!((image.width(), image.height()), (n, n));
            let row = n / 2; // through the centre
            let black: Vec<usize> = (0..n)
                .filter(|&x| image.pixel(x, row) == [0, 0, 0])
                .collect();
            // Runs of black pixels along the row.
            let mut runs: Vec<Vec<usize>> = Vec::new();
            for x in black {
                match runs.last_mut() {
                    Some(run) if *run.last().unwrap() + 1 == x => run.push(x),
                    _ => runs.push(vec![x]),
                }
            }
            assert_eq!(runs.len(), 2, "axis {axis}: runs {runs:?}");
            let px = |x: f64| (x + 1.0) * n as f64 / 2.0 - 0.5;
            for (run, expected) in runs.iter().zip([px(-r), px(r)]) {
                let centre = run.iter().sum::<usize>() as f64 / run.len() as f64;
                assert!(
                    (centre - expected).abs() <= 1.0,
                    "axis {axis}: run {run:?}, expected near {expected}"
                );
            }
            // Inside is blue, outside red.
            let c = image.pixel(n / 2, row);
            assert!(c[2] > c[0], "centre {c:?}");
            let c = image.pixel(2, row);
            assert!(c[0] > c[2], "edge {c:?}");
        }
    }

    #[test]
    fn slice_aspect_ratio() {
        let bounds = Aabb::new([-2.0, -1.0, 0.0], [2.0, 1.0, 1.0]).unwrap();
        let image = render_slice(&sphere(0.5), bounds, 2, 0.5, 100).unwrap();
        assert_eq!((image.width(), image.height()), (100, 50));
        let image = render_slice(&sphere(0.5), bounds, 0, 0.0, 100).unwrap();
        assert_eq!((image.width(), image.height()), (100, 50));
    }

    #[test]
    fn errors() {
        let bad = [0, MAX_IMAGE_SIZE + 1];
        for size in bad {
            let opts = RenderOptions {
                width: size,
                ..RenderOptions::default()
            };
            assert!(matches!(
                render_mesh(&cube(), &opts),
                Err(MeshError::ImageSize { what: "width", .. })
            ));
            let opts = RenderOptions {
                height: size,
                ..RenderOptions::default()
            };
            assert!(matches!(
                render_mesh(&cube(), &opts),
                Err(MeshError::ImageSize { what: "height", .. })
            ));
            let bounds = Aabb::centered_cube(1.0).unwrap();
            assert!(matches!(
                render_slice(&sphere(0.5), bounds, 2, 0.0, size),
                Err(MeshError::ImageSize { .. })
            ));
        }
        let empty = TriMesh::new(vec![[0.0; 3]], vec![]).unwrap();
        assert!(matches!(
            render_mesh(&empty, &RenderOptions::default()),
            Err(MeshError::EmptyMesh)
        ));
        let bounds = Aabb::centered_cube(1.0).unwrap();
        assert!(matches!(
            render_slice(&sphere(0.5), bounds, 3, 0.0, 10),
            Err(MeshError::InvalidSlice { axis: 3, .. })
        ));
        assert!(matches!(
            render_slice(&sphere(0.5), bounds, 0, f64::NAN, 10),
            Err(MeshError::InvalidSlice { .. })
        ));
        let flat = Aabb::new([-1.0, -1.0, 0.0], [1.0, 1.0, 0.0]).unwrap();
        assert!(matches!(
            render_slice(&sphere(0.5), flat, 0, 0.0, 10),
            Err(MeshError::InvalidSlice { .. })
        ));
        // A field that is NaN off the centre line.
        let nan = FnField::new(
            |p: &[f64; 3]| if p[0] > 0.5 { f64::NAN } else { p[0] },
            None,
        );
        match render_slice(&nan, bounds, 2, 0.0, 10) {
            Err(MeshError::NonFiniteSample {
                index, grid_index, ..
            }) => {
                assert_eq!(grid_index, vec![8, 0]);
                assert_eq!(index, 8);
            }
            other => panic!("expected NonFiniteSample, got {other:?}"),
        }
    }

    #[test]
    fn write_png_roundtrip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cube.png");
        let image = render_mesh(&cube(), &RenderOptions::default()).unwrap();
        image.write_png(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes, image.to_png_bytes());
        let (w, h, _) = decode(&bytes);
        assert_eq!((w, h), (512, 512));
        assert!(image.write_png(dir.path().join("missing/x.png")).is_err());
    }

    #[test]
    fn two_d_fields_render_like_slices() {
        let circle = FnField::new(|p: &[f64; 2]| p[0].hypot(p[1]) - 0.5, None);
        let sphere = FnField::new(|p: &[f64; 3]| p[0].hypot(p[1]) - 0.5, None);
        let b2 = Aabb::new([-1.0, -1.0], [1.0, 1.0]).unwrap();
        let b3 = Aabb::new([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]).unwrap();
        let a = render_field_2d(&circle, b2, 64).unwrap();
        let b = render_slice(&sphere, b3, 2, 0.0, 64).unwrap();
        assert_eq!(a, b);
        let flat = Aabb::new([0.0, 0.0], [1.0, 0.0]).unwrap();
        assert!(matches!(
            render_field_2d(&circle, flat, 10),
            Err(MeshError::InvalidSlice { .. })
        ));
        assert!(render_field_2d(&circle, b2, 0).is_err());
        assert_eq!(pixel_of(&b2, 64, 64, &[-1.0, 1.0]), [0.0, 0.0]);
        assert_eq!(pixel_of(&b2, 64, 32, &[0.0, -1.0]), [32.0, 32.0]);
    }

    #[test]
    fn drawing_clips_and_copies() {
        let mut image = Image::filled(10, 8, [255, 255, 255]).unwrap();
        image.fill_disc([2.0, 2.0], 1.0, [1, 2, 3]);
        assert_eq!(image.pixel(1, 1), [1, 2, 3]);
        assert_eq!(image.pixel(3, 3), [255, 255, 255]);
        image.draw_line([0.5, 6.5], [9.5, 6.5], 1.0, [9, 9, 9]);
        assert!((0..10).all(|x| image.pixel(x, 6) == [9, 9, 9]));
        // Off the image: nothing happens, nothing panics.
        image.fill_disc([-50.0, 3.0], 2.0, [0, 0, 0]);
        image.draw_line([-5.0, -5.0], [100.0, -3.0], 3.0, [0, 0, 0]);
        image.set_pixel(-1, 0, [0, 0, 0]);
        image.set_pixel(10, 0, [0, 0, 0]);
        image.fill_disc([f64::NAN, 1.0], 1.0, [0, 0, 0]);
        let small = Image::filled(4, 4, [7, 7, 7]).unwrap();
        image.blit(&small, 8, 6);
        assert_eq!(image.pixel(9, 7), [7, 7, 7]);
        assert_eq!(image.pixel(7, 7), [255, 255, 255]);
    }
}
