// Typeset the maths with the KaTeX copy in docs/assets/katex (works
// offline): on Markdown pages pymdownx.arithmatex (generic mode) wrapped it
// in \( \) and \[ \]; in the notebooks it is Jupyter's $ and $$.  Re-run on
// every page load of mkdocs-material's instant navigation.
function renderMaths() {
  const ignoredClasses = ["highlight", "jp-CodeCell", "jp-OutputArea"];
  renderMathInElement(document.body, {
    delimiters: [
      { left: "\\[", right: "\\]", display: true },
      { left: "\\(", right: "\\)", display: false },
    ],
    ignoredClasses: ignoredClasses,
    throwOnError: false,
  });
  document.querySelectorAll(".jupyter-wrapper .jp-MarkdownCell").forEach((cell) => {
    renderMathInElement(cell, {
      delimiters: [
        { left: "$$", right: "$$", display: true },
        { left: "$", right: "$", display: false },
      ],
      throwOnError: false,
    });
  });
}
if (typeof document$ !== "undefined") {
  document$.subscribe(renderMaths);
} else {
  document.addEventListener("DOMContentLoaded", renderMaths);
}
