"""dofview's own error type: a user mistake (bad file, bad argument), never a bug.

The CLI prints a ``DofviewError`` as one line and exits 2; anything else is a bug and keeps its
traceback.
"""

import importlib


class DofviewError(Exception):
    """A problem the user can fix: the message names the file or argument and what is wrong."""


class DofviewWarning(UserWarning):
    """Something in the input was repaired or dropped (e.g. Gaussians with NaN values)."""


class BackendUnavailable(DofviewError):
    """This GL cannot run the renderer backend asked for (a missing feature or limit); the message
    says what is missing. ``raster="auto"`` catches it and tries the next backend."""


class SceneFormatError(DofviewError):
    """A scene file that is not what its name says (truncated, corrupt, unsupported version); the
    message names the path and what is wrong."""


def require_extra(module: str, extra: str, what: str, instead: str = "") -> None:
    """Check that the optional package ``module`` (installed with ``pip install 'dofview[EXTRA]'``)
    can be imported, before a command's work starts: ``what`` needs it; ``instead`` says how to do
    without it.

    Raises:
        DofviewError: it cannot be imported, naming the extra to install.
    """
    try:
        importlib.import_module(module)
    except ImportError:
        raise DofviewError(f"{what} needs {module}, which is not installed: pip install 'dofview[{extra}]'"
                           + (f" ({instead})" if instead else "")) from None
