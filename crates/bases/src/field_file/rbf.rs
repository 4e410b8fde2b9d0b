//! The `rbf` kind: the stored kernels, [`RbfAny`], its encoder and its body decoder.
//!
//! The `rbf` payload, for the field `s(x) = Σⱼ wⱼ Lⱼʸ φ(|x − y|) + c · (1, (x − m)/h)`:
//!
//! | bytes | content |
//! |---|---|
//! | 4 + t | kernel tag: length `t` (`u32`), then UTF-8 (`r`, `r3`, `tps`, `wendland`) |
//! | 4 + 8·k | kernel parameters: count `k` (`u32`), then `f64`s (`wendland`: the radius) |
//! | 8 | number of functionals `n` (`u64`) |
//! | n·(8·D + 12) | per functional: point (`f64`·D), kind (`u32`: 0 = value, 1 + a = ∂/∂x_a), target (`f64`) |
//! | 8·n | kernel weights `w` (`f64`) |
//! | 8·D + 8 | polynomial centre `m` (`f64`·D) and scale `h` (`f64`) |
//! | 8 + 8·q | polynomial coefficients: count `q = D + 1` (`u64`), then `f64`s |
//! | 16·D | bounding box min then max (`f64`) |

use std::path::Path;

use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::{Aabb, Point};

use super::{Cursor, FieldFileError, KIND_RBF, counted, frame, put_f64s};
use crate::rbf::system::{Functional, Polynomial};
use crate::rbf::{Biharmonic, Kernel, RbfField, ThinPlate, Triharmonic, Wendland};

mod sealed {
    pub trait Sealed {}
    impl Sealed for crate::rbf::Biharmonic {}
    impl Sealed for crate::rbf::Triharmonic {}
    impl Sealed for crate::rbf::ThinPlate {}
    impl Sealed for crate::rbf::Wendland {}
}

/// A kernel the field file stores: the built-in [`Biharmonic`] (`r`), [`Triharmonic`]
/// (`r3`), [`ThinPlate`] (`tps`) and [`Wendland`] (`wendland`, parameter: the radius).
pub trait StoredKernel: Kernel + Clone + sealed::Sealed {
    /// The tag written to the file.
    fn tag(&self) -> &'static str;
    /// The kernel's parameters, in file order.
    fn params(&self) -> Vec<f64>;
    /// The kernel of `tag` with `params`, or `None` if they are not this kernel's.
    fn from_tag(tag: &str, params: &[f64]) -> Option<Self>
    where
        Self: Sized;
    /// `field` as the [`RbfAny`] variant of this kernel.
    fn into_any<const D: usize>(field: RbfField<Self, D>) -> RbfAny<D>
    where
        Self: Sized;
}

impl StoredKernel for Biharmonic {
    fn tag(&self) -> &'static str {
        "r"
    }
    fn params(&self) -> Vec<f64> {
        Vec::new()
    }
    fn from_tag(tag: &str, params: &[f64]) -> Option<Self> {
        (tag == "r" && params.is_empty()).then_some(Biharmonic)
    }
    fn into_any<const D: usize>(field: RbfField<Self, D>) -> RbfAny<D> {
        RbfAny::R(field)
    }
}

impl StoredKernel for Triharmonic {
    fn tag(&self) -> &'static str {
        "r3"
    }
    fn params(&self) -> Vec<f64> {
        Vec::new()
    }
    fn from_tag(tag: &str, params: &[f64]) -> Option<Self> {
        (tag == "r3" && params.is_empty()).then_some(Triharmonic)
    }
    fn into_any<const D: usize>(field: RbfField<Self, D>) -> RbfAny<D> {
        RbfAny::R3(field)
    }
}

impl StoredKernel for ThinPlate {
    fn tag(&self) -> &'static str {
        "tps"
    }
    fn params(&self) -> Vec<f64> {
        Vec::new()
    }
    fn from_tag(tag: &str, params: &[f64]) -> Option<Self> {
        (tag == "tps" && params.is_empty()).then_some(ThinPlate)
    }
    fn into_any<const D: usize>(field: RbfField<Self, D>) -> RbfAny<D> {
        RbfAny::Tps(field)
    }
}

impl StoredKernel for Wendland {
    fn tag(&self) -> &'static str {
        "wendland"
    }
    fn params(&self) -> Vec<f64> {
        vec![self.radius()]
    }
    fn from_tag(tag: &str, params: &[f64]) -> Option<Self> {
        match params {
            [radius] if tag == "wendland" => Wendland::new(*radius),
            _ => None,
        }
    }
    fn into_any<const D: usize>(field: RbfField<Self, D>) -> RbfAny<D> {
        RbfAny::Wendland(field)
    }
}

/// An RBF field with one of the built-in kernels, as read from a file.
#[derive(Debug, Clone)]
pub enum RbfAny<const D: usize> {
    /// `φ(r) = r`.
    R(RbfField<Biharmonic, D>),
    /// `φ(r) = r³`.
    R3(RbfField<Triharmonic, D>),
    /// `φ(r) = r² ln r`.
    Tps(RbfField<ThinPlate, D>),
    /// Wendland's `ψ₃,₁`.
    Wendland(RbfField<Wendland, D>),
}

macro_rules! each_rbf {
    ($self:expr, $f:ident => $body:expr) => {
        match $self {
            RbfAny::R($f) => $body,
            RbfAny::R3($f) => $body,
            RbfAny::Tps($f) => $body,
            RbfAny::Wendland($f) => $body,
        }
    };
}

impl<const D: usize> RbfAny<D> {
    /// The kernel's tag (`r`, `r3`, `tps`, `wendland`).
    pub fn kernel_tag(&self) -> &'static str {
        each_rbf!(self, f => f.kernel().tag())
    }

    /// The centres (the points of the functionals: for an off-surface fit the cloud and its
    /// offset points).
    pub fn centres(&self) -> &[Point<D>] {
        each_rbf!(self, f => f.centres())
    }

    /// The number of centres (functionals).
    pub fn num_centres(&self) -> usize {
        each_rbf!(self, f => f.num_centres())
    }

    /// The kernel weights.
    pub fn weights(&self) -> &[f64] {
        each_rbf!(self, f => f.weights())
    }

    /// The polynomial coefficients.
    pub fn polynomial_coefficients(&self) -> &[f64] {
        each_rbf!(self, f => f.polynomial_coefficients())
    }

    /// The Hessian at `x`.
    pub fn hessian(&self, x: &Point<D>) -> [[f64; D]; D] {
        each_rbf!(self, f => f.hessian(x))
    }
}

impl<const D: usize> ScalarField<D> for RbfAny<D> {
    fn value(&self, p: &Point<D>) -> f64 {
        each_rbf!(self, f => f.value(p))
    }
    fn gradient(&self, p: &Point<D>) -> Point<D> {
        each_rbf!(self, f => f.gradient(p))
    }
    fn values(&self, points: &[Point<D>], out: &mut [f64]) {
        each_rbf!(self, f => f.values(points, out))
    }
    fn bounds(&self) -> Option<Aabb<D>> {
        each_rbf!(self, f => ScalarField::bounds(f))
    }
}

macro_rules! rbf_from {
    ($k:ty, $v:ident) => {
        impl<const D: usize> From<RbfField<$k, D>> for RbfAny<D> {
            fn from(f: RbfField<$k, D>) -> Self {
                RbfAny::$v(f)
            }
        }
    };
}
rbf_from!(Biharmonic, R);
rbf_from!(Triharmonic, R3);
rbf_from!(ThinPlate, Tps);
rbf_from!(Wendland, Wendland);

/// The bytes of the field file of the RBF `field` (version [`VERSION`](super::VERSION)).
pub fn encode_rbf<K: StoredKernel, const D: usize>(field: &RbfField<K, D>) -> Vec<u8> {
    let kernel = field.kernel();
    let tag = kernel.tag();
    let params = kernel.params();
    let f = field.functionals();
    let n = f.len();
    let mut p = Vec::with_capacity(64 + tag.len() + n * (8 * D + 20) + 40 * D);
    p.extend_from_slice(&(tag.len() as u32).to_le_bytes());
    p.extend_from_slice(tag.as_bytes());
    p.extend_from_slice(&(params.len() as u32).to_le_bytes());
    put_f64s(&mut p, &params);
    p.extend_from_slice(&(n as u64).to_le_bytes());
    for j in 0..n {
        put_f64s(&mut p, &f.points[j]);
        let kind = match f.kinds[j] {
            Functional::Value => 0u32,
            Functional::Derivative(a) => 1 + a as u32,
        };
        p.extend_from_slice(&kind.to_le_bytes());
        put_f64s(&mut p, [&f.targets[j]]);
    }
    put_f64s(&mut p, field.weights());
    let poly = field.polynomial();
    put_f64s(&mut p, poly.centre.iter().chain([&poly.scale]));
    let c = field.polynomial_coefficients();
    p.extend_from_slice(&(c.len() as u64).to_le_bytes());
    put_f64s(&mut p, c);
    let bounds = field.bounds;
    put_f64s(&mut p, bounds.min().iter().chain(bounds.max().iter()));
    let mut meta = vec![("kernel", tag.to_string())];
    if !params.is_empty() {
        let list = params
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(",");
        meta.push(("kernel-params", list));
    }
    meta.push(("centres", n.to_string()));
    frame(D, KIND_RBF, &meta, &p)
}

/// The bytes of the field file of the RBF `field`, whatever its kernel.
pub(super) fn encode_any<const D: usize>(field: &RbfAny<D>) -> Vec<u8> {
    each_rbf!(field, f => encode_rbf(f))
}

/// The RBF body; `short` is the error for running out.
pub(super) fn rbf_body<const D: usize>(
    c: &mut Cursor<'_>,
    path: &Path,
    short: impl Fn() -> FieldFileError,
) -> Result<RbfAny<D>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    let tag_len = c.u32().ok_or_else(&short)? as usize;
    let tag = std::str::from_utf8(c.take(tag_len).ok_or_else(&short)?)
        .map_err(|_| malformed("kernel tag is not UTF-8".into()))?
        .to_string();
    let k = c.u32().ok_or_else(&short)?;
    let k = counted(c, path, "kernel parameters", k.into(), 8, 8)?;
    let params = c.f64s(k).ok_or_else(&short)?;
    let n = c.u64().ok_or_else(&short)?;
    // A functional takes its point, kind and target, then its weight: 8·D + 20 bytes in the
    // file; in memory its point, kind, target and weight.
    let n = counted(
        c,
        path,
        "RBF functionals",
        n,
        8 * D + 20,
        std::mem::size_of::<(Point<D>, Functional, f64, f64)>(),
    )?;
    let mut points = Vec::with_capacity(n);
    let mut kinds = Vec::with_capacity(n);
    let mut targets = Vec::with_capacity(n);
    for j in 0..n {
        points.push(c.point::<D>().ok_or_else(&short)?);
        kinds.push(match c.u32().ok_or_else(&short)? {
            0 => Functional::Value,
            a if (a as usize) <= D => Functional::Derivative(a as usize - 1),
            a => {
                return Err(malformed(format!(
                    "functional {j}: unknown kind code {a} for a {D}-D field"
                )));
            }
        });
        targets.push(c.f64().ok_or_else(&short)?);
    }
    let weights = c.f64s(n).ok_or_else(&short)?;
    let centre: Point<D> = c.point().ok_or_else(&short)?;
    let scale = c.f64().ok_or_else(&short)?;
    let q = c.u64().ok_or_else(&short)?;
    if q != D as u64 + 1 {
        return Err(malformed(format!(
            "{q} polynomial coefficients, expected {}",
            D + 1
        )));
    }
    let coefficients = c.f64s(D + 1).ok_or_else(&short)?;
    let min: Point<D> = c.point().ok_or_else(&short)?;
    let max: Point<D> = c.point().ok_or_else(&short)?;
    let all_finite = params
        .iter()
        .chain(points.iter().flatten())
        .chain(&targets)
        .chain(&weights)
        .chain(&centre)
        .chain(&coefficients)
        .all(|v| v.is_finite());
    if !(all_finite && scale.is_finite() && scale > 0.0) {
        return Err(malformed("a non-finite RBF value or scale".into()));
    }
    let bounds = Aabb::new(min, max).map_err(|source| FieldFileError::Invalid {
        path: path.to_owned(),
        source,
    })?;
    let has_derivatives = kinds.iter().any(|k| *k != Functional::Value);
    let poly = Polynomial { centre, scale };
    macro_rules! build {
        ($k:ty, $v:ident) => {{
            let kernel = <$k>::from_tag(&tag, &params).ok_or_else(|| {
                malformed(format!("invalid parameters {params:?} for kernel {tag:?}"))
            })?;
            if has_derivatives && kernel.hessian_at_zero().is_none() {
                return Err(malformed(format!(
                    "gradient functionals with kernel {tag:?}, which is not smooth enough"
                )));
            }
            RbfAny::$v(RbfField::from_parts(
                kernel,
                points,
                kinds,
                targets,
                weights,
                poly,
                coefficients,
                bounds,
            ))
        }};
    }
    Ok(match tag.as_str() {
        "r" => build!(Biharmonic, R),
        "r3" => build!(Triharmonic, R3),
        "tps" => build!(ThinPlate, Tps),
        "wendland" => build!(Wendland, Wendland),
        _ => {
            return Err(FieldFileError::UnknownKernel {
                path: path.to_owned(),
                kernel: tag,
            });
        }
    })
}
