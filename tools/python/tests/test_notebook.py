"""The example notebook (tools/python/examples/first-look.ipynb) runs from top to bottom in a
Jupyter kernel (issue 32 item 3), in a temporary folder, and shows its pictures."""

from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "first-look.ipynb"


def test_the_example_notebook_runs_and_shows_its_pictures(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    pictures = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(pictures) >= 4, "the thumbnail and three renders"
    assert not [o for o in outputs if o.output_type == "error"]
    assert (tmp_path / "phantom_brain.nii.gz").is_file()
