"""The environment the README's commands set up works for the figures the toolbox draws."""


def test_matplotlib_3d_axes_are_available():
    """Debian's python3-matplotlib (a QGIS dependency) must not shadow the venv's mpl_toolkits.mplot3d."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    assert type(ax).__name__ == "Axes3D"
    plt.close(fig)
