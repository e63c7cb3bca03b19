//! Evaluation: the paper's metrics (IE, MS-SSIM and their regional spread) and the
//! analogues of its Tables II, III and IV.

pub mod depth;
pub mod metrics;
pub mod roll;
pub mod tables;
