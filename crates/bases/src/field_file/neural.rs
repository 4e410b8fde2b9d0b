//! The `neural` kind: its encoder and its body decoder.
//!
//! The `neural` payload, for the net `f(x) = o · N((x − c)/h)` of
//! [`NeuralField`] (added within version 2: a reader from before it
//! reports the kind as unknown):
//!
//! | bytes | content |
//! |---|---|
//! | 4 | activation (`u32`: 0 = tanh, 1 = softplus) |
//! | 4 | number of hidden layers `L` (`u32`, at least 1) |
//! | 8·L | hidden widths (`u64`, each at least 1) |
//! | 8·D | input centre `c` (`f64`) |
//! | 8 | input scale `h` (`f64`, > 0) |
//! | 8 | output scale `o` (`f64`, ≠ 0) |
//! | 16·D | bounding box min then max (`f64`) |
//! | 8 | parameter count `n` (`u64`; must be the widths' count) |
//! | 8·n | parameters (`f64`), layer after layer: `W₁` column-major (`w₁ × D`), `b₁`, …, `w_out`, `b_out` |

use std::path::Path;

use zeroset_field_core::geometry::{Aabb, Point};

use super::{Cursor, FieldFileError, KIND_NEURAL, counted, frame, put_f64s};
use crate::neural::{Activation, Architecture, NeuralField};

/// The bytes of the field file of the neural `field` (version [`VERSION`](super::VERSION)).
pub fn encode_neural<const D: usize>(field: &NeuralField<D>) -> Vec<u8> {
    let arch = field.architecture();
    let widths = arch.widths();
    let params = field.parameters();
    let mut p = Vec::with_capacity(8 + 8 * widths.len() + 8 * (3 * D + 3) + 8 * params.len());
    p.extend_from_slice(&arch.activation().code().to_le_bytes());
    p.extend_from_slice(&(widths.len() as u32).to_le_bytes());
    for &w in widths {
        p.extend_from_slice(&(w as u64).to_le_bytes());
    }
    let bounds = field.domain();
    put_f64s(
        &mut p,
        field
            .centre()
            .iter()
            .chain([&field.input_scale(), &field.output_scale()])
            .chain(bounds.min().iter())
            .chain(bounds.max().iter()),
    );
    p.extend_from_slice(&(params.len() as u64).to_le_bytes());
    put_f64s(&mut p, params);
    let list = widths
        .iter()
        .map(|w| w.to_string())
        .collect::<Vec<_>>()
        .join(",");
    frame(
        D,
        KIND_NEURAL,
        &[
            ("activation", arch.activation().name().to_string()),
            ("widths", list),
            ("parameters", params.len().to_string()),
        ],
        &p,
    )
}

/// The neural body; `short` is the error for running out.
pub(super) fn neural_body<const D: usize>(
    c: &mut Cursor<'_>,
    path: &Path,
    short: impl Fn() -> FieldFileError,
) -> Result<NeuralField<D>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    let code = c.u32().ok_or_else(&short)?;
    let activation = Activation::from_code(code)
        .ok_or_else(|| malformed(format!("unknown activation code {code}")))?;
    let layers = c.u32().ok_or_else(&short)?;
    let layers = counted(c, path, "hidden layers", layers.into(), 8, 8)?;
    let mut widths = Vec::with_capacity(layers);
    for _ in 0..layers {
        let w = c.u64().ok_or_else(&short)?;
        widths.push(usize::try_from(w).map_err(|_| malformed(format!("hidden width {w}")))?);
    }
    let arch = Architecture::new(widths, activation)
        .map_err(|e| malformed(format!("invalid network: {e}")))?;
    let centre: Point<D> = c.point().ok_or_else(&short)?;
    let input_scale = c.f64().ok_or_else(&short)?;
    let output_scale = c.f64().ok_or_else(&short)?;
    let min: Point<D> = c.point().ok_or_else(&short)?;
    let max: Point<D> = c.point().ok_or_else(&short)?;
    let n = c.u64().ok_or_else(&short)?;
    let expected = arch.num_parameters(D);
    if n != expected as u64 {
        return Err(malformed(format!(
            "{n} parameters where the widths {:?} need {expected}",
            arch.widths()
        )));
    }
    let expected = counted(c, path, "network parameters", n, 8, 8)?;
    let params = c.f64s(expected).ok_or_else(&short)?;
    let bounds = Aabb::new(min, max).map_err(|source| FieldFileError::Invalid {
        path: path.to_owned(),
        source,
    })?;
    NeuralField::new(arch, params, centre, input_scale, output_scale, bounds)
        .map_err(|e| malformed(format!("invalid neural field: {e}")))
}
