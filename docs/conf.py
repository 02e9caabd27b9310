"""Sphinx configuration of the project's documentation site (``make docs``).

Plain Sphinx settings only, so rosdoc2 can use this file as a package's own conf.py: it renames it,
executes it inside its wrapping conf.py and keeps myst_parser (the one non-Sphinx extension here).
Pages are MyST Markdown; index.rst is the root because rosdoc2 writes its own index.rst where a
source directory has none. Reference pages are generated (tools/docs_reference.py) and committed.
"""

project = "Bracing manipulator"
author = "The bracing project"
copyright = "the bracing project, Apache-2.0"

extensions = ["myst_parser"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "paper_study/*.png"]

# Links to a page's sections by their titles ([text](page.md#a-section-title)), as GitHub renders them.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

html_theme = "furo"
html_title = "Bracing manipulator"
html_static_path: list[str] = []
# No search index of the whole site on each build: the site is small, and this keeps the build quick.
html_copy_source = False
