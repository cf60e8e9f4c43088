"""The Python examples of README.md and docs/python.md run against the installed module
(the Rust side's docs check, tests/cli/docs.rs, makes every such block name this file)."""

import re

PAGES = ["README.md", "docs/python.md"]
MARK = "<!-- check: python python/tests/test_docs.py -->"


def blocks(root, page):
    text = (root / page).read_text()
    found = re.findall(re.escape(MARK) + r"\n```python\n(.*?)\n```", text, flags=re.S)
    fences = text.count("```python")
    assert fences == len(found), f"{page}: {fences} python blocks, {len(found)} marked for this test"
    return found


def test_every_python_example_of_the_pages_runs(root, monkeypatch):
    monkeypatch.chdir(root)
    ran = 0
    for page in PAGES:
        examples = blocks(root, page)
        assert len(examples) >= 1, page
        for k, code in enumerate(examples):
            exec(compile(code, f"{page}, python block {k + 1}", "exec"), {})
            ran += 1
    assert ran >= 2
