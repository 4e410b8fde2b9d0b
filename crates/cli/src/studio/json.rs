//! The API's JSON form of a restoration (`docs/studio.md`), read from requests and written in
//! the state: one type for both directions, so that the two cannot drift apart.

use serde::{Deserialize, Serialize};

use zeroset_field_core::mask::Face;
use zeroset_restore::error::face_name;

use super::session::ApiError;
use crate::restore::Restoration;

fn bad(message: impl Into<String>) -> ApiError {
    ApiError {
        status: 400,
        message: message.into(),
    }
}

/// A restoration as the API's JSON (`docs/studio.md`).
#[derive(Debug, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "lowercase", deny_unknown_fields)]
pub(crate) enum RestorationJson {
    Protrusion {
        mask: [[f64; 3]; 2],
        #[serde(default)]
        face: Option<String>,
        #[serde(default)]
        alpha: Option<f64>,
    },
    Denoise {
        mask: [[f64; 3]; 2],
        coarse: [usize; 3],
        #[serde(default)]
        resampling: Option<String>,
    },
}

impl RestorationJson {
    /// The restoration this asks for, checked: finite corners, a face name, a finite α only
    /// with a face, a known resampling rule, coarse counts of at least 1.
    pub(crate) fn check(self) -> Result<Restoration, ApiError> {
        let finite = |mask: &[[f64; 3]; 2]| {
            if mask.iter().flatten().all(|v| v.is_finite()) {
                Ok(())
            } else {
                Err(bad("mask corners must be finite numbers"))
            }
        };
        match self {
            Self::Protrusion { mask, face, alpha } => {
                finite(&mask)?;
                let face = face.map(|f| f.parse::<Face>()).transpose().map_err(bad)?;
                if alpha.is_some_and(|a| !a.is_finite()) {
                    return Err(bad("alpha must be a finite number or null"));
                }
                if alpha.is_some() && face.is_none() {
                    return Err(bad(
                        "alpha is the slope across the face: give a face, or alpha null",
                    ));
                }
                Ok(Restoration::Protrusion { mask, face, alpha })
            }
            Self::Denoise {
                mask,
                coarse,
                resampling,
            } => {
                finite(&mask)?;
                let point_resampling = match resampling.as_deref() {
                    None | Some("area") => false,
                    Some("point") => true,
                    Some(other) => {
                        return Err(bad(format!(
                            "resampling is \"area\" or \"point\", got {other:?}"
                        )));
                    }
                };
                if coarse.contains(&0) {
                    return Err(bad("coarse cell counts must be at least 1"));
                }
                Ok(Restoration::Denoise {
                    mask,
                    coarse,
                    point_resampling,
                })
            }
        }
    }
}

impl From<&Restoration> for RestorationJson {
    fn from(r: &Restoration) -> Self {
        match *r {
            Restoration::Protrusion { mask, face, alpha } => Self::Protrusion {
                mask,
                face: face.map(face_name),
                alpha,
            },
            Restoration::Denoise {
                mask,
                coarse,
                point_resampling,
            } => Self::Denoise {
                mask,
                coarse,
                resampling: Some(if point_resampling { "point" } else { "area" }.to_owned()),
            },
        }
    }
}
