"""The user page's example (docs/book/src/python.md) runs as written."""
import re

from conftest import REPO


def test_the_user_pages_example_runs(tmp_path, monkeypatch):
    page = (REPO / "docs" / "book" / "src" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, re.S)
    assert len(blocks) == 1, "the page has one Python example"
    assert len(blocks[0].strip().splitlines()) <= 10, "the example is ten lines at most"
    monkeypatch.chdir(tmp_path)  # it writes python-out.exr where it runs
    exec(compile(blocks[0], "python.md", "exec"), {})
    assert (tmp_path / "python-out.exr").exists()
