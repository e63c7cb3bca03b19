//! Evaluation: the paper's metrics (IE, MS-SSIM and their regional spread).

pub mod metrics;
