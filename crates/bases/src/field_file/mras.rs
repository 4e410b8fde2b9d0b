//! The `mras` kind: its encoder and its body decoder.
//!
//! The `mras` payload, for the [`MrasField`] `f = L · Σ_k o_k((p − origin)/L)` (added within
//! version 2: a reader from before it reports the kind as unknown). Every number is stored
//! exactly, so a field read back evaluates to the same bits. A level's geometry follows from
//! `k`, `m` and `α` ([`LevelGeometry`](crate::mras::LevelGeometry): the root's splines span the
//! cube, the other levels' the box `c ± α√D·s` around each cell):
//!
//! | bytes | content |
//! |---|---|
//! | 8·D | cube origin (`f64`) |
//! | 8 | cube side `L` (`f64`, > 0) |
//! | 8 | partition-of-unity factor `α` (`f64`, > ½) |
//! | 4 | number of levels `K` (`u32`) |
//! | … | `K` levels, each: level `k` (`u32`, 1, 2, … in order), B-splines per axis `m` (`u32`), cell count `n` (`u64`), then `n` cells |
//! | … | a cell: lattice index (`D × u32`, each below `2^{k−1}`), storage (`u32`: 0 = CP factors, 1 = full tensor), then for CP the rank `R` (`u32`, ≥ 1) and `D` factor matrices `m × R` row-major (`f64`), for a full tensor `m^D` coefficients row-major (`f64`) |
//! | 8 | optional: number of recorded input points `P` (`u64`) |
//! | 4·D·P | their unit-cube coordinates `(p − origin)/L` (`f32`, finite) |
//!
//! The recorded points ([`MrasField::points`]) are what `zeroset mesh` checks the mesh's
//! components against; a file without them (written before fields recorded them, or a field
//! built by hand) ends after the last level. A reader from before the points were added
//! refuses a file that has them ("bytes of payload left over").

use std::path::Path;

use zeroset_field_core::geometry::Point;

use super::{Cursor, FieldFileError, KIND_MRAS, counted, frame, put_f64s};
use crate::mras::{CellSpline, MAX_LEVEL, MrasCell, MrasField, MrasLevel};

/// The bytes of the field file of the MRAS `field` (version [`VERSION`](super::VERSION)).
pub fn encode_mras<const D: usize>(field: &MrasField<D>) -> Vec<u8> {
    let mut p = Vec::with_capacity(64 + 8 * field.storage());
    put_f64s(
        &mut p,
        field
            .origin()
            .iter()
            .chain([field.side(), field.alpha()].iter()),
    );
    p.extend_from_slice(&(field.levels().len() as u32).to_le_bytes());
    let mut cells = 0;
    for level in field.levels() {
        p.extend_from_slice(&level.level().to_le_bytes());
        p.extend_from_slice(&(level.knots() as u32).to_le_bytes());
        p.extend_from_slice(&(level.cells().len() as u64).to_le_bytes());
        cells += level.cells().len();
        for cell in level.cells() {
            for i in cell.index {
                p.extend_from_slice(&i.to_le_bytes());
            }
            match &cell.spline {
                CellSpline::Cp { rank, factors } => {
                    p.extend_from_slice(&0u32.to_le_bytes());
                    p.extend_from_slice(&(*rank as u32).to_le_bytes());
                    for f in factors {
                        put_f64s(&mut p, f);
                    }
                }
                CellSpline::Full { coefficients } => {
                    p.extend_from_slice(&1u32.to_le_bytes());
                    put_f64s(&mut p, coefficients);
                }
            }
        }
    }
    let points = field.unit_points();
    if !points.is_empty() {
        p.extend_from_slice(&(points.len() as u64).to_le_bytes());
        for u in points {
            for v in u {
                p.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    frame(
        D,
        KIND_MRAS,
        &[
            ("levels", field.levels().len().to_string()),
            ("cells", cells.to_string()),
            ("storage", field.storage().to_string()),
            ("uncompressed", field.uncompressed_storage().to_string()),
            ("points", points.len().to_string()),
        ],
        &p,
    )
}

/// The MRAS body; `short` is the error for running out.
pub(super) fn mras_body<const D: usize>(
    c: &mut Cursor<'_>,
    path: &Path,
    short: impl Fn() -> FieldFileError,
) -> Result<MrasField<D>, FieldFileError> {
    let malformed = |reason: String| FieldFileError::Malformed {
        path: path.to_owned(),
        reason,
    };
    let origin: Point<D> = c.point().ok_or_else(&short)?;
    let side = c.f64().ok_or_else(&short)?;
    let alpha = c.f64().ok_or_else(&short)?;
    let count = c.u32().ok_or_else(&short)?;
    // Levels are numbered 1, 2, … up to MAX_LEVEL: checked here, before each level builds its
    // cell lookup, so that a forged count or numbering cannot make thousands of them.
    if count > MAX_LEVEL {
        return Err(malformed(format!("{count} levels (at most {MAX_LEVEL})")));
    }
    let mut levels = Vec::with_capacity(count as usize);
    for position in 1..=count {
        let level = c.u32().ok_or_else(&short)?;
        if level != position {
            return Err(malformed(format!(
                "levels must be numbered 1, 2, …: position {position} holds level {level}"
            )));
        }
        let knots = c.u32().ok_or_else(&short)? as usize;
        if !(3..=64).contains(&knots) {
            return Err(malformed(format!(
                "level {level}: {knots} B-splines per axis"
            )));
        }
        let n = c.u64().ok_or_else(&short)?;
        // A cell takes at least 4(D + 2) bytes: refuse counts the bytes left cannot hold.
        let n = counted(
            c,
            path,
            &format!("level {level} cells"),
            n,
            4 * (D + 2),
            std::mem::size_of::<MrasCell<D>>(),
        )?;
        let mut cells = Vec::with_capacity(n);
        for _ in 0..n {
            let mut index = [0u32; D];
            for i in &mut index {
                *i = c.u32().ok_or_else(&short)?;
            }
            let spline = match c.u32().ok_or_else(&short)? {
                0 => {
                    let rank = c.u32().ok_or_else(&short)? as usize;
                    if rank == 0 || rank > knots.pow(2) {
                        return Err(malformed(format!("level {level}: CP rank {rank}")));
                    }
                    let what = format!("level {level}: CP factors of rank {rank}");
                    counted(c, path, &what, (D * knots * rank) as u64, 8, 8)?;
                    let mut factors: [Vec<f64>; D] = std::array::from_fn(|_| Vec::new());
                    for f in &mut factors {
                        *f = c.f64s(knots * rank).ok_or_else(&short)?;
                    }
                    CellSpline::Cp { rank, factors }
                }
                1 => {
                    let what = format!("level {level}: full tensor of {knots}^{D} coefficients");
                    let n = counted(c, path, &what, knots.pow(D as u32) as u64, 8, 8)?;
                    CellSpline::Full {
                        coefficients: c.f64s(n).ok_or_else(&short)?,
                    }
                }
                code => {
                    return Err(malformed(format!(
                        "level {level}: cell storage code {code}"
                    )));
                }
            };
            cells.push(MrasCell { index, spline });
        }
        levels.push(MrasLevel::new(level, knots, cells).map_err(malformed)?);
    }
    let field = MrasField::new(origin, side, alpha, levels).map_err(malformed)?;
    if c.remaining() == 0 {
        return Ok(field);
    }
    let count = c.u64().ok_or_else(&short)?;
    let n = counted(
        c,
        path,
        "recorded points",
        count,
        4 * D,
        std::mem::size_of::<[f32; D]>(),
    )?;
    let mut points = Vec::with_capacity(n);
    for index in 0..n {
        let mut u = [0f32; D];
        for v in &mut u {
            *v = f32::from_bits(c.u32().ok_or_else(&short)?);
        }
        if u.iter().any(|v| !v.is_finite()) {
            return Err(malformed(format!(
                "recorded point {index}: {u:?} is not finite"
            )));
        }
        points.push(u);
    }
    Ok(field.with_unit_points(points))
}
