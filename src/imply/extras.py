"""The package's optional extras, by the modules they bring: what a command that needs a missing one says.

The core (``pip install imply``) runs what a user runs: ``imply score``, ``evaluate``, ``diagnose``, ``sim``,
``table`` and ``suite``. The study's workflow steps need ``imply[study]``; MP4 video needs ``imply[video]``
(PNG frames need only the core); parquet files need ``imply[parquet]`` (CSV only the core); released V-JEPA 2
weights need ``imply[vjepa2]``. ``pyproject.toml`` lists each extra's distributions; a test holds this map to it.
"""

from __future__ import annotations

# top-level module -> (the extra that installs it, its distribution's name)
EXTRA_OF_MODULE: dict[str, tuple[str, str]] = {
    "torch": ("study", "torch"),
    "snakemake": ("study", "snakemake"),
    "pybullet": ("study", "pybullet"),
    "sapien": ("study", "sapien"),
    "av": ("video", "av"),
    "pyarrow": ("parquet", "pyarrow"),
    "transformers": ("vjepa2", "transformers"),
    "snakemake_executor_plugin_slurm": ("cluster", "snakemake-executor-plugin-slurm"),
}

# what the core leaves out although a dependency's own extra would bring it: mujoco[sysid]'s HTML report
NOT_IN_CORE: tuple[str, ...] = ("plotly", "imageio", "imageio_ffmpeg")


def missing_extra(exc: ImportError) -> str | None:
    """One line naming the extra that would bring the module ``exc`` did not find, or None where the module is
    none of the extras' (a user's own import error, left to its caller)."""
    if not isinstance(exc, ModuleNotFoundError) or not exc.name:
        return None
    module = exc.name.split(".")[0]
    if module not in EXTRA_OF_MODULE:
        return None
    extra, distribution = EXTRA_OF_MODULE[module]
    return (
        f"this needs {distribution}, which the '{extra}' extra installs: pip install 'imply[{extra}]' "
        f"(in a clone: pip install -e '.[{extra}]')"
    )
