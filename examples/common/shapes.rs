//! Oriented point samples of analytic shapes (outward unit normals), shared by the MRAS
//! example, bench and tests.

#![allow(dead_code)]

/// Points and their normals.
pub type Cloud = (Vec<[f64; 3]>, Vec<[f64; 3]>);

/// `n` points of the sphere of radius `r` about the origin (Fibonacci lattice).
pub fn sphere(n: usize, r: f64) -> Cloud {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let d = [
                s * (golden * i as f64).cos(),
                s * (golden * i as f64).sin(),
                z,
            ];
            (d.map(|v| v * r), d)
        })
        .unzip()
}

/// A torus (radii `big`, `small`) around the z axis on an `nu × nv` parameter grid, every
/// other ring shifted by half a step.
pub fn torus(nu: usize, nv: usize, big: f64, small: f64) -> Cloud {
    let mut pts = Vec::new();
    let mut nrm = Vec::new();
    for i in 0..nu {
        let u = 2.0 * std::f64::consts::PI * i as f64 / nu as f64;
        for j in 0..nv {
            let v = 2.0 * std::f64::consts::PI * (j as f64 + 0.5 * (i % 2) as f64) / nv as f64;
            nrm.push([v.cos() * u.cos(), v.cos() * u.sin(), v.sin()]);
            pts.push([
                (big + small * v.cos()) * u.cos(),
                (big + small * v.cos()) * u.sin(),
                small * v.sin(),
            ]);
        }
    }
    (pts, nrm)
}
