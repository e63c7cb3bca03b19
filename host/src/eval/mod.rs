//! Evaluation: the paper's metrics (IE, MS-SSIM and their regional spread) and the
//! analogues of its Tables II, III and IV and of its defect-detection comparison.

pub mod anomaly;
pub mod depth;
pub mod detect;
pub mod metrics;
pub mod report;
pub mod roll;
pub mod tables;
