//! The volume grid shared by the modelling stages (see CONVENTIONS: cubic cells, cell
//! (i, j, k) centred at origin + (idx + 0.5)·cell, linear index i + nx·(j + ny·k)).

use serde::{Deserialize, Serialize};

/// A uniform grid of cubic cells in volume space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    pub dims: [u32; 3],
    /// Corner of cell (0, 0, 0) in volume space.
    pub origin: [f32; 3],
    /// Edge of a cell (px).
    pub cell: f32,
}

impl Grid {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Linear index of cell (i, j, k).
    pub fn index(&self, i: u32, j: u32, k: u32) -> usize {
        i as usize + self.dims[0] as usize * (j as usize + self.dims[1] as usize * k as usize)
    }

    /// The cell holding grid coordinates `g` (its nearest cell centre), or `None` outside the
    /// grid or for non-finite coordinates.
    pub fn cell_of(&self, g: [f32; 3]) -> Option<usize> {
        let mut c = [0u32; 3];
        for a in 0..3 {
            // Written as a positive test so NaN falls outside.
            if !(g[a] >= 0.0 && g[a] < self.dims[a] as f32) {
                return None;
            }
            c[a] = (g[a].floor() as u32).min(self.dims[a] - 1);
        }
        Some(self.index(c[0], c[1], c[2]))
    }

    /// Grid coordinates of a volume-space point.
    pub fn to_grid(&self, p: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|a| (p[a] - self.origin[a]) / self.cell)
    }

    /// Volume-space point of grid coordinates.
    pub fn to_volume(&self, g: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|a| self.origin[a] + g[a] * self.cell)
    }

    /// (i, j, k) of a linear index.
    pub fn coords(&self, idx: usize) -> [u32; 3] {
        let (nx, ny) = (self.dims[0] as usize, self.dims[1] as usize);
        [
            (idx % nx) as u32,
            (idx / nx % ny) as u32,
            (idx / (nx * ny)) as u32,
        ]
    }

    /// Centre of cell (i, j, k) in volume space.
    pub fn centre(&self, c: [u32; 3]) -> [f32; 3] {
        std::array::from_fn(|a| self.origin[a] + (c[a] as f32 + 0.5) * self.cell)
    }

    /// The cell (i, j, k) containing the volume-space point `p`, if inside the grid.
    pub fn cell_at(&self, p: [f32; 3]) -> Option<[u32; 3]> {
        let g = self.to_grid(p);
        let mut c = [0u32; 3];
        for a in 0..3 {
            let f = g[a].floor();
            if !(f >= 0.0 && f < self.dims[a] as f32) {
                return None;
            }
            c[a] = f as u32;
        }
        Some(c)
    }
}
