"""The paper's metrics, as ``rollfuse metrics`` reports them: information entropy (IE),
MS-SSIM against a reference, and their spread over strips (eqs. 8–9)."""

from ._rollfuse import ie, ms_ssim, strip_std

__all__ = ["ie", "ms_ssim", "strip_std"]
