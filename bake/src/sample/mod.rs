//! Low-discrepancy sampling: an Owen-scrambled Sobol sequence and importance sampling of density
//! grids by its points (paper §5.1).
