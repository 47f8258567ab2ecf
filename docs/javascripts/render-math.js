// Renders the equations of a page with the KaTeX files this site serves (javascripts/katex/).
// pymdownx.arithmatex (generic mode) leaves each one in an element of class "arithmatex":
// inline <span>\(…\)</span>, display <div>\[…\]</div>.  document$ is Material's page
// observable: it emits on the first load and after every instant navigation.  An equation
// KaTeX cannot read stays as its TeX, marked with class "math-error" and the reason.
document$.subscribe(({ body }) => {
  for (const element of body.querySelectorAll(".arithmatex")) {
    const source = element.textContent.trim();
    try {
      katex.render(source.slice(2, -2), element, {
        displayMode: element.tagName === "DIV",
        throwOnError: true,
      });
    } catch (error) {
      element.classList.add("math-error");
      element.title = error.message;
      console.error(error);
    }
  }
});
