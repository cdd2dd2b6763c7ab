"""dofview: a camera lens (focus, aperture, exposure) for trained 3D Gaussian Splatting scenes."""

__version__ = "0.1.0"
