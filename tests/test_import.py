"""``import dynslip`` has no side effects but float64 (/work/shared/docs/style.md, "A library
has no side effects at import"; issue 43): it keeps JAX's platform, edits no environment
variable (``XLA_FLAGS`` included), creates no folder (the compilation cache), starts no thread
and imports no matplotlib. The command line's runtime is set by
:func:`dynslip._jaxconfig.configure_runtime`, which :func:`dynslip.cli.main` calls.

Each check runs in a new Python process: this one was configured by ``tests/conftest.py``.
"""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: what configure_runtime puts in the environment (and so the pytest process's own)
CONFIGURED = ("JAX_PLATFORMS", "XLA_FLAGS", "EQX_ON_ERROR", "JAX_COMPILATION_CACHE_DIR",
              "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS",
              "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "DYNSLIP_CACHE_DIR", "JAX_ENABLE_X64")


def _env(tmp_path: Path, **extra: str) -> dict[str, str]:
    """A clean environment: none of the runtime's variables, HOME and the caches in tmp_path."""
    env = {k: v for k, v in os.environ.items() if k not in CONFIGURED}
    env.update(HOME=str(tmp_path / "home"), XDG_CACHE_HOME=str(tmp_path / "home" / ".cache"),
               MPLCONFIGDIR=str(tmp_path / "mpl"), **extra)
    (tmp_path / "home").mkdir()
    return env


def _python(script: str, env: dict[str, str]) -> None:
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-4000:]


IMPORT = """
    import os, sys, threading
    import jax
    from jax._src import xla_bridge

    platform = jax.config.jax_platforms
    env = dict(os.environ)
    threads = threading.active_count()
    import dynslip

    assert jax.config.jax_platforms == platform, (platform, jax.config.jax_platforms)
    changed = sorted(set(env.items()) ^ set(os.environ.items()))
    assert not changed, changed
    assert os.environ.get("XLA_FLAGS") == env.get("XLA_FLAGS")
    assert jax.config.jax_enable_x64
    assert jax.config.jax_compilation_cache_dir is None
    assert "matplotlib" not in sys.modules
    assert threading.active_count() == threads
    assert not xla_bridge.backends_are_initialized()  # no device chosen yet
    assert jax.numpy.asarray(1.0).dtype == jax.numpy.float64
"""


@pytest.mark.parametrize("xla_flags", [None, "--xla_cpu_enable_fast_math=false"])
def test_import_has_no_side_effect_but_float64(tmp_path, xla_flags):
    extra = {} if xla_flags is None else {"XLA_FLAGS": xla_flags}
    env = _env(tmp_path, DYNSLIP_CACHE_DIR=str(tmp_path / "cache"), **extra)
    _python(IMPORT, env)
    assert not (tmp_path / "cache").exists()
    assert list((tmp_path / "home").iterdir()) == []  # no ~/.cache/dynslip/jax either


def test_import_keeps_the_default_cache_folder_uncreated(tmp_path):
    """Without DYNSLIP_CACHE_DIR the default folder is under HOME: not created either."""
    _python(IMPORT, _env(tmp_path))
    assert list((tmp_path / "home").iterdir()) == []


CONFIGURE = """
    import os, subprocess, sys, warnings
    import equinox as eqx
    import jax
    import dynslip
    from dynslip._jaxconfig import XLA_FLAG, configure_runtime

    xla_before = os.environ.get("XLA_FLAGS")
    warnings.simplefilter("error")  # after `import dynslip` (and equinox), nothing is too late
    cache = configure_runtime()
    assert configure_runtime() == cache  # idempotent
    expected = os.environ.get("EXPECTED_CACHE") or None
    assert (str(cache) if cache else None) == expected, (cache, expected)
    assert jax.config.jax_compilation_cache_dir == expected
    assert os.environ.get("JAX_COMPILATION_CACHE_DIR") == expected
    if expected:
        assert jax.config.jax_persistent_cache_min_compile_time_secs == 0.5
        assert jax.config.jax_persistent_cache_min_entry_size_bytes == 0
    assert jax.config.jax_platforms == "cpu" == os.environ["JAX_PLATFORMS"]
    assert os.environ["EQX_ON_ERROR"] == "nan"
    # equinox, imported before, checks as NaN all the same: a failed check poisons, not raises
    checked = jax.jit(lambda x: eqx.error_if(x, x > 0, "a failed check"))(jax.numpy.ones(2))
    assert bool(jax.numpy.isnan(checked).all())
    if xla_before and "xla_cpu_use_fusion_emitters" in xla_before:
        assert os.environ["XLA_FLAGS"] == xla_before  # the user's choice wins
    else:
        assert os.environ["XLA_FLAGS"].split()[-1] == XLA_FLAG
    assert jax.numpy.arange(3.0).sum() == 3.0  # the backend starts with them
    # a child process (a sweep's worker) inherits the settings through the environment
    child = subprocess.run([sys.executable, "-c", "import jax; print(jax.config.jax_platforms, "
                            "jax.config.jax_compilation_cache_dir)"],
                           capture_output=True, text=True, check=True)
    assert child.stdout.split() == ["cpu", str(expected)], child.stdout
"""


@pytest.mark.parametrize("xla_flags", [None, "--xla_cpu_use_fusion_emitters=true"])
def test_configure_runtime_sets_what_the_command_line_needs(tmp_path, xla_flags):
    cache = tmp_path / "cache"
    extra = {} if xla_flags is None else {"XLA_FLAGS": xla_flags}
    env = _env(tmp_path, DYNSLIP_CACHE_DIR=str(cache), EXPECTED_CACHE=str(cache), **extra)
    _python(CONFIGURE, env)
    assert cache.is_dir()


def test_configure_runtime_without_a_cache_folder(tmp_path):
    """A cache folder that cannot be made (its parent is a file): no persistent cache, none
    inherited from the environment either."""
    (tmp_path / "afile").write_text("")
    env = _env(tmp_path, DYNSLIP_CACHE_DIR=str(tmp_path / "afile" / "cache"), EXPECTED_CACHE="",
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "elsewhere"))
    _python(CONFIGURE, env)
    assert not (tmp_path / "elsewhere").exists()


def test_the_command_line_configures_the_runtime(tmp_path):
    cache = tmp_path / "cache"
    env = _env(tmp_path, DYNSLIP_CACHE_DIR=str(cache))
    run = subprocess.run([sys.executable, "-m", "dynslip.cli", "validate",
                          str(ROOT / "scenarios" / "method2.yaml")], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-4000:]
    assert "Warning" not in run.stderr, run.stderr[-4000:]
    assert cache.is_dir()


def test_the_suite_runs_with_the_runtime():
    """tests/conftest.py configured this process as the command line configures its own."""
    import jax

    assert os.environ["XLA_FLAGS"].count("xla_cpu_use_fusion_emitters") == 1
    assert jax.config.jax_platforms == os.environ["JAX_PLATFORMS"]
    assert os.environ["EQX_ON_ERROR"]
    import equinox._errors

    assert equinox._errors.EQX_ON_ERROR == os.environ["EQX_ON_ERROR"]  # the mode checks use
