"""Photos of a capture as the truth a render is measured against: datasets (INRIA model
folders, COLMAP, nerfstudio), image metrics (PSNR, SSIM, FLIP, LPIPS), evaluation."""
