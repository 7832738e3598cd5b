// Active Sketch panel: the /sketch page of the same server (same origin, behind the same door
// and the same control table), loaded only while its panel is shown.
"use strict";
umbra.on("layout", () => {
  const panel = document.querySelector('[data-panel="sketch"]'), frame = $("sketch-frame");
  if (!panel.hidden && !frame.getAttribute("src")) frame.src = "sketch?embed=1";  // no header of its own
  if (panel.hidden && frame.getAttribute("src")) frame.removeAttribute("src");
});
