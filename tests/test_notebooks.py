"""The teacher-design notebook, tiny mode, executed top to bottom with nbclient."""

import os

import pytest

pytestmark = pytest.mark.slow  # a Jupyter kernel (tests/test_tiers.py)
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_teacher_designs_notebook_runs_in_tiny_mode(monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    from jupyter_client.kernelspec import KernelSpecManager

    if "python3" not in KernelSpecManager().find_kernel_specs():
        pytest.skip("no python3 kernel spec (pip install ipykernel)")
    monkeypatch.setenv("NOTEBOOK_SIZE", "tiny")
    monkeypatch.setenv("JAX_PLATFORMS", "cpu")
    monkeypatch.setenv("PYTHONPATH", ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    path = os.path.join(ROOT, "experiments", "notebooks", "teacher_designs.ipynb")
    nb = nbformat.read(path, as_version=4)
    first = next(c for c in nb.cells if c.cell_type == "code")
    assert 'SIZE = os.environ.get("NOTEBOOK_SIZE", "tiny")' in first.source
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": ROOT}}).execute()
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "swept values are live: ok" in text
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "display_data" and "image/png" in o.get("data", {})]
    assert len(images) >= 3
