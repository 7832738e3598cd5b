// Zoom panel: a slider per camera the graph gives the console (none: no panel).
"use strict";
umbra.on("state", (s) => {
  for (const z of s.zoom) {
    let input = document.getElementById(`zoom-${z.name}`);
    if (!input) {
      const label = document.createElement("label");
      label.textContent = `${z.name} `;
      input = document.createElement("input");
      Object.assign(input, { id: `zoom-${z.name}`, type: "range", min: 0, max: 1, step: 0.01 });
      const shown = document.createElement("span");
      shown.id = `zoom-${z.name}-value`;
      input.addEventListener("change", () => umbra.send("zoom", { camera: z.name, value: Number(input.value) }));
      label.append(input, " ", shown); $("zoom").append(label, document.createElement("br"));
    }
    if (document.activeElement !== input) input.value = z.value;
    $(`zoom-${z.name}-value`).textContent = `${z.value.toFixed(2)} (0 wide .. 1 tele)`;
  }
});
