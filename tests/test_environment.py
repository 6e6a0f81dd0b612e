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
