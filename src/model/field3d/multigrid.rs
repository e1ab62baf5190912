//! The multigrid hierarchy: levels, 2x2x2 coarsening, the dense inverse of the coarsest level.

use super::{neighbours6, Prepared};
use crate::base::grid::Grid;
use crate::error::{Error, Result};
use crate::stages::field_cfg::Config;
use rayon::prelude::*;

/// One level of the hierarchy, as the shaders see it.
pub(super) struct Level {
    pub(super) dims: [u32; 3],
    /// -1 outside H, else the penalty weight.
    pub(super) cellw: Vec<f32>,
    /// Weights of the links to the +x, +y, +z neighbour, 3 per cell (0: none).
    pub(super) links: Vec<f32>,
    /// Finest-level H cells under each cell.
    pub(super) vol: Vec<f32>,
    /// Finest-level links crossing to the +x, +y, +z neighbour, 3 per cell.
    pub(super) cross: Vec<f32>,
    pub(super) sigma: f32,
    pub(super) cells: usize,
}

impl Level {
    pub(super) fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    pub(super) fn cfg(&self, colour: u32, mode: u32, coarse: Option<&Level>, count: u32) -> Config {
        let c = coarse.map_or([0; 3], |l| l.dims);
        Config {
            nx: self.dims[0],
            ny: self.dims[1],
            nz: self.dims[2],
            colour,
            sigma: self.sigma,
            mode,
            cnx: c[0],
            cny: c[1],
            cnz: c[2],
            count,
        }
    }

    /// The next coarser level: a coarse cell is in H when any child is, with the mean
    /// penalty of the finest H cells under it (the Galerkin value of the penalty for the
    /// mean restriction and constant interpolation), and a Laplacian scaled by a further 1/4
    /// (cells twice as wide) whose links follow the finest ones: two neighbouring blocks are
    /// linked only if finest links cross between them. Why: a plain rediscretisation links every pair of blocks holding H cells, so
    /// sheets of H that the fine level keeps apart (hair above and below an ear, either
    /// side of a thin gap) merge on coarse levels; the coarse correction is then wrong for
    /// them and the cycle stalled or diverged on photos.
    pub(super) fn coarsen(&self) -> Level {
        let [nx, ny, nz] = self.dims;
        let dims = self.dims.map(|d| d.div_ceil(2));
        let nc: usize = dims.iter().map(|&d| d as usize).product();
        let mut pen_vol = vec![0.0f64; nc];
        let mut vol = vec![0.0f32; nc];
        let mut cross = vec![0.0f32; 3 * nc];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let i = (x + nx * (y + ny * z)) as usize;
                    if self.cellw[i] < 0.0 {
                        continue;
                    }
                    let ic = (x / 2 + dims[0] * (y / 2 + dims[1] * (z / 2))) as usize;
                    pen_vol[ic] += self.cellw[i] as f64 * self.vol[i] as f64;
                    vol[ic] += self.vol[i];
                    // Only links that leave the block (from an odd coordinate) cross.
                    for (a, c) in [x, y, z].into_iter().enumerate() {
                        if c % 2 == 1 {
                            cross[3 * ic + a] += self.cross[3 * i + a];
                        }
                    }
                }
            }
        }
        let cellw: Vec<f32> = (0..nc)
            .map(|i| {
                if vol[i] > 0.0 {
                    (pen_vol[i] / vol[i] as f64) as f32
                } else {
                    -1.0
                }
            })
            .collect();
        let cells = vol.iter().filter(|&&v| v > 0.0).count();
        // Blocks are linked (weight 1, as full blocks) when finest links cross between them.
        // Weights that follow the crossing count per volume were tried and made the cycle a
        // far worse preconditioner: the prolongation is trilinear and does not see them.
        let links: Vec<f32> = cross.iter().map(|&f| (f > 0.0) as u32 as f32).collect();
        Level {
            dims,
            cellw,
            links,
            vol,
            cross,
            sigma: self.sigma * 0.25,
            cells,
        }
    }

    /// Compact list of H cells and the f32 inverse of `σ² L² + P` over them (f64 Cholesky).
    pub(super) fn direct_inverse(&self) -> Result<(Vec<u32>, Vec<f32>)> {
        let cells: Vec<u32> = (0..self.len() as u32)
            .filter(|&i| self.cellw[i as usize] >= 0.0)
            .collect();
        let m = cells.len();
        let mut pos = vec![u32::MAX; self.len()];
        for (k, &c) in cells.iter().enumerate() {
            pos[c as usize] = k as u32;
        }
        // Sparse rows of σL over the compact list.
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        let s = self.sigma as f64;
        let lrows: Vec<Vec<(usize, f64)>> = cells
            .iter()
            .enumerate()
            .map(|(k, &c)| {
                let i = c as usize;
                let cand = neighbours6(i, [nx, ny, nz]);
                let mut row: Vec<(usize, f64)> = cand
                    .iter()
                    .enumerate()
                    .filter(|(_, (ok, j))| *ok && pos[*j] != u32::MAX)
                    .map(|(e, &(_, j))| {
                        (pos[j] as usize, s * self.links[3 * i.min(j) + e / 2] as f64)
                    })
                    .filter(|&(_, w)| w > 0.0)
                    .collect();
                let d: f64 = row.iter().map(|&(_, w)| w).sum();
                row.push((k, -d));
                row
            })
            .collect();
        let mut a = vec![0.0f64; m * m];
        // (σL)² = Σ_k (row k)ᵀ(row k) since L is symmetric.
        for row in &lrows {
            for &(i, vi) in row {
                for &(j, vj) in row {
                    a[i * m + j] += vi * vj;
                }
            }
        }
        for (k, &c) in cells.iter().enumerate() {
            a[k * m + k] += self.cellw[c as usize] as f64;
        }
        let inv = spd_inverse(&mut a, m).ok_or_else(|| {
            Error::Invalid("coarsest field operator is not positive definite".into())
        })?;
        Ok((cells, inv.iter().map(|&x| x as f32).collect()))
    }
}

/// Inverse of a symmetric positive definite matrix by Cholesky (a is overwritten).
pub(super) fn spd_inverse(a: &mut [f64], m: usize) -> Option<Vec<f64>> {
    for j in 0..m {
        let mut d = a[j * m + j];
        for k in 0..j {
            d -= a[j * m + k] * a[j * m + k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        a[j * m + j] = d;
        for i in j + 1..m {
            let mut s = a[i * m + j];
            for k in 0..j {
                s -= a[i * m + k] * a[j * m + k];
            }
            a[i * m + j] = s / d;
        }
    }
    // Solve L Lᵀ X = I column by column (columns in parallel).
    let cols: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .map(|c| {
            let mut y = vec![0.0f64; m];
            for i in c..m {
                let mut s = if i == c { 1.0 } else { 0.0 };
                for k in c..i {
                    s -= a[i * m + k] * y[k];
                }
                y[i] = s / a[i * m + i];
            }
            for i in (0..m).rev() {
                let mut s = y[i];
                for k in i + 1..m {
                    s -= a[k * m + i] * y[k];
                }
                y[i] = s / a[i * m + i];
            }
            y
        })
        .collect();
    let mut inv = vec![0.0f64; m * m];
    for (c, col) in cols.iter().enumerate() {
        for (r, &v) in col.iter().enumerate() {
            inv[r * m + c] = v;
        }
    }
    Some(inv)
}

/// Builds the level hierarchy from the prepared fine problem.
pub(super) fn hierarchy(grid: &Grid, prep: &Prepared, max_direct: usize) -> Vec<Level> {
    let cellw: Vec<f32> = prep
        .inside
        .iter()
        .zip(&prep.pen)
        .map(|(&b, &p)| if b { p } else { -1.0 })
        .collect();
    let cells = prep.inside.iter().filter(|&&b| b).count();
    let dims = grid.dims.map(|d| d as usize);
    let mut links = vec![0.0f32; 3 * prep.inside.len()];
    for (i, &inside) in prep.inside.iter().enumerate() {
        if inside {
            for (e, (ok, j)) in neighbours6(i, dims).into_iter().enumerate() {
                // The +x, +y, +z entries (odd e) own the link.
                if e % 2 == 1 && ok && prep.inside[j] {
                    links[3 * i + e / 2] = 1.0;
                }
            }
        }
    }
    let vol = prep.inside.iter().map(|&b| b as u32 as f32).collect();
    let mut levels = vec![Level {
        dims: grid.dims,
        cellw,
        cross: links.clone(),
        links,
        vol,
        sigma: 1.0,
        cells,
    }];
    loop {
        let l = levels.last().expect("at least the fine level");
        if l.cells <= max_direct || l.dims.iter().all(|&d| d == 1) {
            break;
        }
        let c = l.coarsen();
        levels.push(c);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::field3d::prepare;

    #[test]
    pub(super) fn coarse_links_follow_fine_connectivity() {
        // Two slabs of H, x in 0..=2 and 4..=7, apart at x = 3. Block x 1 (cells 2, 3) holds
        // the end of the first slab, block 2 (cells 4, 5) the start of the second: no fine
        // link crosses between them, so the coarse level must not link them either.
        let grid = Grid {
            dims: [8, 4, 4],
            origin: [0.0; 3],
            cell: 1.0,
        };
        let h: Vec<u32> = (0..grid.len()).map(|i| (i % 8 != 3) as u32).collect();
        let cons = [(0u32, [1.0, 0.0, 0.0]), (7u32, [1.0, 0.0, 0.0])];
        let prep = prepare(&grid, &h, &cons, 10.0).unwrap();
        let levels = hierarchy(&grid, &prep, 1);
        let c = &levels[1];
        assert_eq!(c.dims, [4, 2, 2]);
        for row in (0..16).step_by(4) {
            let x_links: Vec<f32> = (0..4).map(|x| c.links[3 * (row + x)]).collect();
            assert_eq!(x_links, [1.0, 0.0, 1.0, 0.0], "row {row}");
        }
        // Volumes and penalty: block 1 holds 4 of its 8 cells, block 0 all 8.
        assert_eq!(c.vol[1], 4.0);
        assert_eq!(c.vol[0], 8.0);
    }
}
