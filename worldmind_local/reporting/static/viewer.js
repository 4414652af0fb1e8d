// Keyboard navigation between episodes (left/right arrows follow the prev/next links). No network.
(function () {
  "use strict";
  document.addEventListener("keydown", function (event) {
    var id = event.key === "ArrowLeft" ? "prev" : event.key === "ArrowRight" ? "next" : null;
    if (!id || event.target.tagName === "INPUT") { return; }
    var link = document.getElementById(id);
    if (link && link.getAttribute("href")) { window.location.href = link.getAttribute("href"); }
  });
  document.documentElement.setAttribute("data-viewer", "ready");
})();
