//! Evaluation: the paper's metrics (IE, MS-SSIM and their regional spread) and the
//! analogues of its Tables II and III.

pub mod metrics;
pub mod tables;
