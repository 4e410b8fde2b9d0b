//! The studio's session: the input, the restorations committed so far (with undo and redo), and
//! the live previews — everything the HTTP API does, without HTTP.
//!
//! Each state of the history keeps its field and that field's samples on the restoration grid.
//! A preview restores the current samples (`O(grid)` copy, `O(mask)` solve) and meshes them by
//! marching cubes at the grid's resolution; the quadratic spline through them is only built when
//! a restoration is committed. A commit does what `zeroset restore` does on the current field —
//! the same samples, the same [`Restoration::restore`], the same spline — so a saved field has
//! the bits of the chain of `zeroset restore` commands that [`Session::commands`] prints.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use serde_json::{Value, json};

use zeroset_bases::bspline::BSplineField;
use zeroset_bases::field_file::write_field;
use zeroset_field_core::field::ScalarField;
use zeroset_field_core::geometry::Point;
use zeroset_field_core::grid::Grid;
use zeroset_field_core::io::shell_word;
use zeroset_mesh::voxel::{self, Detail};
use zeroset_mesh::{McOptions, PlyFormat, TriMesh, marching_cubes, mesh_field, write_ply};

use crate::restore::{Loaded, Report, Restoration, Source, interpolate};

use super::json::RestorationJson;
use super::wire;

/// Why a request failed: the HTTP status and a sentence for the user.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct ApiError {
    /// 4xx for the request's fault, 500 for the studio's.
    pub status: u16,
    /// What is wrong.
    pub message: String,
}

impl ApiError {
    /// `400 Bad Request`: the restoration asked for cannot be done.
    pub(crate) fn bad_request(err: &anyhow::Error) -> Self {
        Self {
            status: 400,
            message: crate::message(err),
        }
    }

    /// `409 Conflict`: the request does not fit the session's state.
    pub(crate) fn conflict(message: impl Into<String>) -> Self {
        Self {
            status: 409,
            message: message.into(),
        }
    }

    /// `500`: the studio failed (e.g. writing a file).
    pub(crate) fn internal(err: &anyhow::Error) -> Self {
        Self {
            status: 500,
            message: crate::message(err),
        }
    }
}

/// One state of the history: a field and its samples on the session's grid.
struct State {
    field: Field,
    samples: Vec<f64>,
}

/// The field of a state: the input as read, or a restoration's spline (what Save writes).
enum Field {
    Input(Box<dyn ScalarField<3>>),
    Restored(BSplineField<3>),
}

impl Field {
    fn as_field(&self) -> &dyn ScalarField<3> {
        match self {
            Self::Input(field) => field.as_ref(),
            Self::Restored(field) => field,
        }
    }
}

/// A committed restoration and the α it used.
#[derive(Debug, Clone)]
struct Step {
    restoration: Restoration,
    alpha_used: Option<f64>,
}

/// How the input was read: what the command lines repeat.
#[derive(Debug, Clone)]
pub(crate) struct Origin {
    /// The input as the user named it.
    pub input: PathBuf,
    /// `--grid`, if given.
    pub grid: Option<[usize; 3]>,
    /// `--neighbours`, for point clouds (given or not).
    pub neighbours: Option<usize>,
    /// `--format`, if given.
    pub format: Option<String>,
    /// `--positive-inside`.
    pub positive_inside: bool,
}

impl Origin {
    /// What the [`Source`] arguments say.
    pub(crate) fn of(source: &Source) -> Self {
        Self {
            input: source.input.clone(),
            grid: source.grid,
            neighbours: source.neighbours,
            format: source.format.clone(),
            positive_inside: source.positive_inside,
        }
    }
}

/// The studio's state. Not thread-safe by itself: the server holds it behind a mutex.
pub(crate) struct Session {
    origin: Origin,
    convention: zeroset_restore::protrusion::Convention,
    description: String,
    grid: Grid<3>,
    /// Subtracted from positions sent to the page (the centre of the grid's box).
    offset: Point<3>,
    points: Option<Vec<Point<3>>>,
    output: Option<PathBuf>,
    /// `history[0]` is the input; `history[i]` the field after `steps[i - 1]`.
    history: Vec<State>,
    steps: Vec<Step>,
    /// How many steps are in effect.
    position: usize,
    /// The input field's slope near its surface (median `|∇f|`, by central differences of its
    /// samples next to the zero level; 0 if none are): the α slider reaches 4× it.
    slope: f64,
}

/// The most restorations one session holds (each keeps its grid samples and spline, so that undo
/// and redo are instant) ...
const MAX_HISTORY: usize = 64;

/// ... and the most memory they may take together ([`crate::restore::state_bytes`] each: at
/// 128³ cells 32 restorations, at 256³ four). A full history refuses Apply (save, and go on in
/// a new studio on the result).
const HISTORY_BYTES: u64 = 1 << 30;

impl Session {
    /// A session on the loaded input (`source` says how it was read), saving to `output`.
    pub(crate) fn new(source: &Source, loaded: Loaded, output: Option<PathBuf>) -> Self {
        let grid = loaded.grid;
        let samples = grid.sample(loaded.field.as_ref());
        let slope = surface_slope(&grid, &samples);
        Self {
            origin: Origin::of(source),
            convention: source.convention(),
            description: loaded.description,
            offset: grid.bounds().center(),
            grid,
            points: loaded.points,
            output,
            history: vec![State {
                field: Field::Input(loaded.field),
                samples,
            }],
            steps: Vec::new(),
            position: 0,
            slope,
        }
    }

    /// The restoration grid.
    pub(crate) fn grid(&self) -> &Grid<3> {
        &self.grid
    }

    /// The current state: the field with the steps in effect.
    fn current(&self) -> &State {
        &self.history[self.position]
    }

    /// Checks a restoration against the grid and restores the current samples.
    fn restore(&self, restoration: &Restoration) -> Result<crate::restore::Restored, ApiError> {
        let state = self.current();
        let mask = restoration
            .mask(&self.grid)
            .map_err(|e| ApiError::bad_request(&e))?;
        restoration
            .check_size(&self.grid, &mask, self.origin.grid.is_some())
            .map_err(|e| ApiError::bad_request(&e))?;
        restoration
            .restore(
                state.field.as_field(),
                &self.grid,
                &state.samples,
                &mask,
                self.convention,
            )
            .map_err(|e| ApiError::bad_request(&e))
    }

    /// The surface of `samples` by marching cubes on the grid, outward normals.
    fn surface(&self, samples: &[f64]) -> Result<TriMesh, ApiError> {
        let negated: Vec<f64>;
        let values = match self.convention {
            zeroset_restore::protrusion::Convention::NegativeInside => samples,
            zeroset_restore::protrusion::Convention::PositiveInside => {
                negated = samples.iter().map(|v| -v).collect();
                &negated
            }
        };
        marching_cubes(&self.grid, values, 0.0, &McOptions::default())
            .map_err(|e| ApiError::internal(&anyhow::Error::new(e).context("meshing")))
    }

    /// The committed surface as a binary mesh ([`wire::mesh`]).
    pub(crate) fn mesh(&self) -> Result<Vec<u8>, ApiError> {
        let start = Instant::now();
        let mesh = self.surface(&self.current().samples)?;
        let report = MeshReport {
            mesh_ms: start.elapsed().as_secs_f64() * 1e3,
            commands: self.commands(None),
            ..MeshReport::default()
        };
        Ok(report.with(&mesh, self.offset))
    }

    /// The surface `restoration` would give, not committed: a binary mesh whose report carries
    /// the α used, the default α and the command lines.
    pub(crate) fn preview(&self, restoration: &Restoration) -> Result<Vec<u8>, ApiError> {
        let start = Instant::now();
        let restored = self.restore(restoration)?;
        let restore_ms = start.elapsed().as_secs_f64() * 1e3;
        let (alpha_used, default_alpha) = self.alphas(restoration, &restored)?;
        let start = Instant::now();
        let mesh = self.surface(&restored.samples)?;
        let mesh_ms = start.elapsed().as_secs_f64() * 1e3;
        let alpha_range = default_alpha.map(|a| alpha_range(a, self.slope));
        let report = MeshReport {
            restore_ms,
            mesh_ms,
            alpha_used,
            default_alpha,
            alpha_range,
            commands: self.commands(Some(restoration)),
        };
        Ok(report.with(&mesh, self.offset))
    }

    /// The α a protrusion removal used and the field's own mean slope across its face (the
    /// default, computed apart when α was given).
    fn alphas(
        &self,
        restoration: &Restoration,
        restored: &crate::restore::Restored,
    ) -> Result<(Option<f64>, Option<f64>), ApiError> {
        let Report::Protrusion(report) = &restored.report else {
            return Ok((None, None));
        };
        let Restoration::Protrusion { face, alpha, .. } = restoration else {
            return Ok((None, None));
        };
        let default = match alpha {
            None => report.alpha,
            Some(_) => {
                let mask = restoration
                    .mask(&self.grid)
                    .map_err(|e| ApiError::bad_request(&e))?;
                zeroset_restore::protrusion::Protrusion {
                    face: *face,
                    alpha: None,
                    convention: self.convention,
                    ..Default::default()
                }
                .system(&self.grid, &self.current().samples, &mask)
                .map_err(|e| ApiError::bad_request(&anyhow::Error::new(e)))?
                .alpha()
            }
        };
        Ok((report.alpha, default))
    }

    /// Commits `restoration`: the current field restored and interpolated by the quadratic
    /// spline, as `zeroset restore` writes it. Drops the steps that could be redone.
    pub(crate) fn apply(&mut self, restoration: &Restoration) -> Result<(), ApiError> {
        let capacity = self.history_capacity();
        if self.position >= capacity {
            return Err(ApiError::conflict(format!(
                "the studio holds {capacity} restorations on this grid: save, and go on in a new \
                 studio on the saved field"
            )));
        }
        let restored = self.restore(restoration)?;
        let alpha_used = match &restored.report {
            Report::Protrusion(r) => r.alpha,
            Report::Denoise { .. } => None,
        };
        let field: BSplineField<3> =
            interpolate(&self.grid, restored.samples).map_err(|e| ApiError::bad_request(&e))?;
        // What `zeroset restore` samples when it reads this field back from its file.
        let samples = self.grid.sample(&field);
        self.history.truncate(self.position + 1);
        self.steps.truncate(self.position);
        self.history.push(State {
            field: Field::Restored(field),
            samples,
        });
        self.steps.push(Step {
            restoration: restoration.clone(),
            alpha_used,
        });
        self.position += 1;
        Ok(())
    }

    /// The number of restorations a session holds: [`MAX_HISTORY`], fewer on large grids
    /// ([`HISTORY_BYTES`] in all), at least one.
    fn history_capacity(&self) -> usize {
        let per_state = crate::restore::state_bytes(&self.grid).max(1);
        ((HISTORY_BYTES / per_state) as usize).clamp(1, MAX_HISTORY)
    }

    /// One step back.
    pub(crate) fn undo(&mut self) -> Result<(), ApiError> {
        if self.position == 0 {
            return Err(ApiError::conflict("nothing to undo"));
        }
        self.position -= 1;
        Ok(())
    }

    /// One step forward.
    pub(crate) fn redo(&mut self) -> Result<(), ApiError> {
        if self.position == self.steps.len() {
            return Err(ApiError::conflict("nothing to redo"));
        }
        self.position += 1;
        Ok(())
    }

    /// Writes the current field to the output and, with `with_mesh`, its mesh as `zeroset mesh
    /// OUT.zsf -o OUT.ply` makes it (marching cubes, general detail, binary PLY) beside it: both
    /// files are written in full under temporary names first and only then renamed over the
    /// outputs, so that a failure replaces neither. The answer names a mesh beside the output
    /// that this save did not write (`stale_mesh`: it shows another field).
    pub(crate) fn save(&self, with_mesh: bool) -> Result<Value, ApiError> {
        let Some(output) = &self.output else {
            return Err(ApiError::conflict(
                "the studio was started without -o OUT.zsf: there is nowhere to save",
            ));
        };
        let Field::Restored(field) = &self.current().field else {
            return Err(ApiError::conflict(
                "nothing to save yet: apply a restoration first",
            ));
        };
        let mesh_path = output.with_extension("ply");
        let staged = |path: &Path| {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            path.with_file_name(format!(".{name}.studio-save"))
        };
        let (field_tmp, mesh_tmp) = (staged(output), staged(&mesh_path));
        let written = (|| -> anyhow::Result<()> {
            write_field(&field_tmp, field)
                .with_context(|| format!("writing {}", output.display()))?;
            if with_mesh {
                save_mesh(field, &mesh_tmp)
                    .with_context(|| format!("writing {}", mesh_path.display()))?;
                std::fs::rename(&mesh_tmp, &mesh_path)
                    .with_context(|| format!("writing {}", mesh_path.display()))?;
            }
            std::fs::rename(&field_tmp, output)
                .with_context(|| format!("writing {}", output.display()))
        })();
        if let Err(e) = written {
            let _ = std::fs::remove_file(&field_tmp);
            let _ = std::fs::remove_file(&mesh_tmp);
            return Err(ApiError::internal(
                &e.context(format!("{} was not replaced", output.display())),
            ));
        }
        let bytes = std::fs::metadata(output).map(|m| m.len()).unwrap_or(0);
        let stale = !with_mesh && mesh_path.exists();
        Ok(json!({
            "field": output.display().to_string(),
            "mesh": with_mesh.then(|| mesh_path.display().to_string()),
            "stale_mesh": stale.then(|| mesh_path.display().to_string()),
            "bytes": bytes,
        }))
    }

    /// The input points as [`wire::points`], or `None` for a field file.
    pub(crate) fn points(&self) -> Option<Vec<u8>> {
        self.points
            .as_ref()
            .map(|points| wire::points(points, self.offset))
    }

    /// The session's state as the API's JSON.
    pub(crate) fn state(&self) -> Value {
        let bounds = self.grid.bounds();
        let spacing = self.grid.spacing();
        let first = self.grid.point([0, 0, 0]);
        let steps: Vec<Value> = self
            .steps
            .iter()
            .map(|s| {
                let mut v =
                    serde_json::to_value(RestorationJson::from(&s.restoration)).unwrap_or_default();
                v["alpha_used"] = json!(s.alpha_used);
                v
            })
            .collect();
        json!({
            "input": self.origin.input.display().to_string(),
            "description": self.description,
            "output": self.output.as_ref().map(|p| p.display().to_string()),
            "bounds": [bounds.min(), bounds.max()],
            "grid": {"counts": self.grid.counts(), "first": first, "spacing": spacing},
            "offset": self.offset,
            "steps": steps,
            "position": self.position,
            "can_undo": self.position > 0,
            "can_redo": self.position < self.steps.len(),
            "commands": self.commands(None),
            "points": self.points.as_ref().map(Vec::len),
            "positive_inside": self.origin.positive_inside,
        })
    }

    /// The `zeroset restore` command lines that reproduce the steps in effect, then `extra`:
    /// one per step, the intermediate files named `OUT.step1.zsf`, … and the last one the
    /// output (or `restored.zsf` without `-o`).
    pub(crate) fn commands(&self, extra: Option<&Restoration>) -> Vec<String> {
        let steps: Vec<&Restoration> = self.steps[..self.position]
            .iter()
            .map(|s| &s.restoration)
            .chain(extra)
            .collect();
        let output = self
            .output
            .clone()
            .unwrap_or_else(|| PathBuf::from("restored.zsf"));
        let stem = output.with_extension("");
        let file = |i: usize| -> PathBuf {
            if i + 1 == steps.len() {
                output.clone()
            } else {
                PathBuf::from(format!("{}.step{}.zsf", stem.display(), i + 1))
            }
        };
        let o = &self.origin;
        steps
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let mut line = String::from("zeroset restore ");
                if i == 0 {
                    line.push_str(&shell_word(&o.input));
                    if let Some(g) = o.grid {
                        line.push_str(&format!(" --grid {},{},{}", g[0], g[1], g[2]));
                    }
                    if let Some(k) = o.neighbours {
                        line.push_str(&format!(" --neighbours {k}"));
                    }
                    if let Some(f) = &o.format {
                        line.push_str(&format!(" --format {}", shell_word(Path::new(f))));
                    }
                } else {
                    line.push_str(&shell_word(&file(i - 1)));
                }
                if o.positive_inside {
                    line.push_str(" --positive-inside");
                }
                line.push(' ');
                line.push_str(&r.flags());
                line.push_str(" -o ");
                line.push_str(&shell_word(&file(i)));
                line
            })
            .collect()
    }
}

/// The report a binary mesh carries (`docs/studio.md`; [`wire::mesh`] adds the counts).
#[derive(Debug, Default, serde::Serialize)]
struct MeshReport {
    restore_ms: f64,
    mesh_ms: f64,
    /// The α of the restoration.
    alpha_used: Option<f64>,
    /// The field's mean slope across the face: the slider's mark.
    default_alpha: Option<f64>,
    alpha_range: Option<[f64; 2]>,
    /// The command lines that reproduce the surface.
    commands: Vec<String>,
}

impl MeshReport {
    /// `mesh` with this report, as [`wire::mesh`] lays it out.
    fn with(self, mesh: &TriMesh, offset: Point<3>) -> Vec<u8> {
        wire::mesh(serde_json::to_value(self).unwrap_or_default(), mesh, offset)
    }
}

/// A slider range for α: from −r to r, `r` the larger of 8|α₀| (the default `alpha`) and 4×
/// the field's `slope` near its surface (1 if both are 0). The default is the mean slope across
/// the face, which the protrusion's own cross-section can bring near 0 (or below it: −0.04 on
/// the bundled bunny's ears), where ±8|α₀| could not reach the α that flattens (1–3 on a
/// distance-like field).
fn alpha_range(alpha: f64, slope: f64) -> [f64; 2] {
    let mut scale = 0.0f64;
    if alpha.is_finite() {
        scale = scale.max(8.0 * alpha.abs());
    }
    if slope.is_finite() {
        scale = scale.max(4.0 * slope);
    }
    if scale == 0.0 {
        scale = 1.0;
    }
    [-scale, scale]
}

/// The median `|∇f|` of `samples` on `grid` by central differences, at the interior samples
/// next to the zero level (a neighbour of the other sign); 0 where none are.
fn surface_slope(grid: &Grid<3>, samples: &[f64]) -> f64 {
    let [nx, ny, nz] = grid.counts();
    let h = grid.spacing();
    let at = |i: usize, j: usize, k: usize| samples[(i * ny + j) * nz + k];
    let mut norms = Vec::new();
    for i in 1..nx.saturating_sub(1) {
        for j in 1..ny.saturating_sub(1) {
            for k in 1..nz.saturating_sub(1) {
                let inside = at(i, j, k) < 0.0;
                let neighbours = [
                    at(i - 1, j, k),
                    at(i + 1, j, k),
                    at(i, j - 1, k),
                    at(i, j + 1, k),
                    at(i, j, k - 1),
                    at(i, j, k + 1),
                ];
                if neighbours.iter().all(|&v| (v < 0.0) == inside) {
                    continue;
                }
                let g = [
                    (at(i + 1, j, k) - at(i - 1, j, k)) / (2.0 * h[0]),
                    (at(i, j + 1, k) - at(i, j - 1, k)) / (2.0 * h[1]),
                    (at(i, j, k + 1) - at(i, j, k - 1)) / (2.0 * h[2]),
                ];
                let n = g.iter().map(|v| v * v).sum::<f64>().sqrt();
                if n.is_finite() {
                    norms.push(n);
                }
            }
        }
    }
    if norms.is_empty() {
        return 0.0;
    }
    norms.sort_by(f64::total_cmp);
    norms[norms.len() / 2]
}

/// Writes the mesh `zeroset mesh FIELD -o PATH` writes by default: marching cubes on voxels of
/// the general detail's size, normals from the field's gradient, binary PLY, atomically.
fn save_mesh(field: &BSplineField<3>, path: &Path) -> anyhow::Result<()> {
    let bounds = field.bounds().context("the field has no bounds")?;
    let grid = voxel::grid_for(&bounds, voxel::voxel_size(&bounds, Detail::General), 0.0)
        .context("building the meshing grid")?;
    let mesh = mesh_field(field, &grid, 0.0, &McOptions::default()).context("meshing")?;
    write_ply(path, &mesh, PlyFormat::BinaryLittleEndian)
        .with_context(|| format!("writing {}", path.display()))
}
