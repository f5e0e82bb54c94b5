"""Every notebook under docs/notebooks/ runs from top to bottom without an error.

The notebooks run in a kernel of *this* interpreter: a kernelspec whose argv is
``sys.executable -m ipykernel_launcher`` is written to a temporary folder and looked up there
alone, so no ``python3`` kernelspec installed elsewhere (user or system Jupyter folders) can
pick another Python. Nothing beyond ``pip install -e .[train,dev]`` is needed.
"""

from pathlib import Path

import nbformat
import pytest
from ipykernel.kernelspec import write_kernel_spec
from jupyter_client.kernelspec import KernelSpecManager
from jupyter_client.manager import AsyncKernelManager
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "docs" / "notebooks").glob("*.ipynb"))
KERNEL = "activeperc-tests"
CELL_TIMEOUT_S = 120


@pytest.fixture(scope="module")
def kernel_dirs(tmp_path_factory):
    """A folder holding one kernelspec that starts this interpreter's ipykernel."""
    root = tmp_path_factory.mktemp("kernels")
    write_kernel_spec(str(root / KERNEL))
    return [str(root)]


def test_notebooks_exist():
    assert NOTEBOOKS, "no notebooks found under docs/notebooks/"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path, kernel_dirs):
    nb = nbformat.read(path, as_version=4)
    assert all(c.get("outputs", []) == [] for c in nb.cells if c.cell_type == "code"), (
        f"{path.name} is stored with outputs; clear them before committing"
    )
    km = AsyncKernelManager(kernel_name=KERNEL, kernel_spec_manager=KernelSpecManager(kernel_dirs=kernel_dirs))
    client = NotebookClient(
        nb,
        km=km,
        kernel_name=KERNEL,
        timeout=CELL_TIMEOUT_S,
        allow_errors=False,
        resources={"metadata": {"path": str(path.parent)}},
    )
    client.execute()  # raises CellExecutionError, naming the cell, if any cell fails
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
