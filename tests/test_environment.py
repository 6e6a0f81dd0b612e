"""The environment the README's commands set up works for the figures the toolbox draws."""


def test_matplotlib_3d_axes_are_available():
    """Debian's python3-matplotlib (a QGIS dependency) must not shadow the venv's mpl_toolkits.mplot3d."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mpl_toolkits.mplot3d import Axes3D

    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    assert isinstance(ax, Axes3D)
    assert tuple(int(v) for v in matplotlib.__version__.split(".")[:2]) >= (3, 8)  # the venv's wheel, not Debian's 3.6
    plt.close(fig)


def test_the_command_list_and_a_commands_help_import_no_numerical_library():
    """``gistools --help`` and ``gistools rasters --help`` import neither numpy nor GDAL, PROJ, pandas or the
    product modules: each command's module imports its libraries when it runs (start-up in a tenth of a second)."""
    import subprocess
    import sys

    heavy = ("numpy", "rasterio", "pyproj", "pandas", "geopandas", "laspy", "scipy", "gistools.products.rasters")
    for words in (["--help"], ["rasters", "--help"], ["shrub", "--help"], ["bands", "--help"]):
        script = ("import sys\nfrom gistools.cli.main import cli\n"
                  f"try:\n    cli({words!r}, prog_name='gistools')\nexcept SystemExit:\n    pass\n"
                  f"print([m for m in {heavy!r} if m in sys.modules])")
        run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stderr
        assert run.stdout.strip().splitlines()[-1] == "[]", (words, run.stdout[-300:])


def test_a_rasters_run_without_vector_inputs_imports_no_vector_or_table_library(tmp_path):
    """``gistools rasters`` on tiles alone (no water or road features) imports neither shapely, pyogrio, pandas,
    geopandas nor matplotlib: each costs a run's start 0.02-0.3 s, and only the features' steps need them."""
    import subprocess
    import sys

    from conftest import SAMPLE

    unused = ("shapely", "pyogrio", "pandas", "geopandas", "matplotlib")
    words = ["rasters", str(SAMPLE), "--out", str(tmp_path / "out"), "-q"]
    script = ("import sys\nfrom gistools.cli.main import cli\n"
              f"try:\n    cli({words!r}, prog_name='gistools')\n"
              "except SystemExit as e:\n    assert not e.code, e.code\n"
              f"print([m for m in {unused!r} if m in sys.modules])")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().splitlines()[-1] == "[]", run.stdout[-300:]
