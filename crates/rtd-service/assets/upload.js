// Upload page for `rtd serve`: mode switch, drop zones and the job upload.
(function () {
  "use strict";

  var MAX_FILE_BYTES = 64 * 1024 * 1024;
  var FIELDS = {
    denoise: { files: ["color", "guide", "albedo", "normal"], text: [] },
    render: { files: ["scene"], text: ["spp", "width", "height", "camera"] },
  };
  var COMMON_TEXT = ["name", "email"];

  var form = document.getElementById("upload-form");
  var submit = document.getElementById("submit");
  var errorEl = document.getElementById("error");
  var bar = document.getElementById("upload-progress");
  var statusEl = document.getElementById("upload-status");
  var denoiseFields = document.getElementById("denoise-fields");
  var renderFields = document.getElementById("render-fields");
  var modeDenoise = document.getElementById("mode-denoise");
  var modeRender = document.getElementById("mode-render");

  function $(id) { return document.getElementById(id); }

  function showError(msg) {
    errorEl.textContent = msg;
    errorEl.hidden = !msg;
  }

  function mode() { return modeRender.checked ? "render" : "denoise"; }

  function applyMode() {
    var render = mode() === "render";
    renderFields.hidden = !render;
    renderFields.disabled = !render;
    denoiseFields.hidden = render;
    denoiseFields.disabled = render;
    showError("");
  }

  function formatSize(bytes) {
    if (bytes < 1024) return bytes + " B";
    if (bytes < 1024 * 1024) return (bytes / 1024).toFixed(1) + " KiB";
    return (bytes / (1024 * 1024)).toFixed(1) + " MiB";
  }

  // Drop zones: each .drop wraps one file input, its file name label and a clear button.
  var refreshers = [];

  function setupDrop(zone) {
    var input = $(zone.getAttribute("data-input"));
    var nameEl = zone.querySelector(".drop-file");
    var clear = zone.querySelector(".clear");

    function refresh() {
      var f = input.files && input.files[0];
      nameEl.textContent = f ? f.name + " (" + formatSize(f.size) + ")" : "No file chosen";
      zone.classList.toggle("has-file", !!f);
      clear.hidden = !f;
    }

    refreshers.push(refresh);
    input.addEventListener("change", refresh);
    clear.addEventListener("click", function () {
      input.value = "";
      refresh();
      input.focus();
    });
    zone.addEventListener("dragenter", function (e) {
      e.preventDefault();
      zone.classList.add("dragging");
    });
    zone.addEventListener("dragover", function (e) {
      e.preventDefault();
      if (e.dataTransfer) e.dataTransfer.dropEffect = "copy";
      zone.classList.add("dragging");
    });
    zone.addEventListener("dragleave", function (e) {
      if (!zone.contains(e.relatedTarget)) zone.classList.remove("dragging");
    });
    zone.addEventListener("drop", function (e) {
      e.preventDefault();
      zone.classList.remove("dragging");
      var files = e.dataTransfer && e.dataTransfer.files;
      if (!files || !files.length || input.matches(":disabled")) return;
      var dt = new DataTransfer();
      dt.items.add(files[0]);
      input.files = dt.files;
      input.dispatchEvent(new Event("change", { bubbles: true }));
    });
    refresh();
  }

  function fileOf(id) {
    var input = $(id);
    return input.files && input.files.length ? input.files[0] : null;
  }

  // Returns an error sentence, or "" when the form looks complete.
  function validate(m) {
    var names = FIELDS[m].files;
    for (var i = 0; i < names.length; i++) {
      var f = fileOf(names[i]);
      if (f && f.size > MAX_FILE_BYTES) return "The file " + f.name + " is larger than 64 MiB.";
    }
    if (m === "render") {
      if (!fileOf("scene")) return "Choose a .glb or .gltf scene to render.";
      return "";
    }
    if (!fileOf("color")) return "Choose the noisy render to denoise.";
    if (fileOf("normal") && !fileOf("albedo")) return "A normal image needs an albedo image too.";
    return "";
  }

  function buildData(m) {
    var data = new FormData();
    FIELDS[m].files.forEach(function (id) {
      var f = fileOf(id);
      if (f) data.append(id, f, f.name);
    });
    FIELDS[m].text.concat(COMMON_TEXT).forEach(function (id) {
      var v = $(id).value.trim();
      if (v !== "") data.append(id, v);
    });
    return data;
  }

  function setBusy(busy) {
    submit.disabled = busy;
    submit.textContent = busy ? "Uploading…" : "Upload";
    bar.hidden = !busy;
    if (!busy) statusEl.textContent = "";
  }

  function onSubmit(e) {
    e.preventDefault();
    var m = mode();
    var problem = validate(m);
    if (problem) { showError(problem); return; }
    showError("");
    setBusy(true);
    bar.value = 0;
    bar.removeAttribute("value"); // indeterminate until the first progress event

    var xhr = new XMLHttpRequest();
    xhr.open("POST", "/api/jobs");
    xhr.setRequestHeader("Accept", "application/json");
    xhr.upload.onprogress = function (ev) {
      if (!ev.lengthComputable || !ev.total) return;
      bar.value = ev.loaded / ev.total;
      statusEl.textContent = Math.round((100 * ev.loaded) / ev.total) + "% uploaded";
    };
    xhr.upload.onload = function () { statusEl.textContent = "Uploaded, creating the job…"; };
    xhr.onload = function () {
      var body = null;
      try { body = JSON.parse(xhr.responseText); } catch (_) { body = null; }
      if (xhr.status === 201 && body && typeof body.key === "string" && /^[0-9a-fA-F]+$/.test(body.key)) {
        statusEl.textContent = "Job created.";
        window.location.href = "/jobs/" + encodeURIComponent(body.key);
        return;
      }
      setBusy(false);
      if (body && typeof body.error === "string" && body.error) showError(body.error);
      else showError("The upload failed (HTTP " + xhr.status + ").");
    };
    xhr.onerror = function () {
      setBusy(false);
      showError("The upload did not reach the server; check the connection and try again.");
    };
    xhr.onabort = function () { setBusy(false); };
    xhr.send(buildData(m));
  }

  modeDenoise.addEventListener("change", applyMode);
  modeRender.addEventListener("change", applyMode);
  Array.prototype.forEach.call(document.querySelectorAll(".drop[data-input]"), setupDrop);
  form.addEventListener("submit", onSubmit);

  // Dropping a file outside a zone should not navigate away from the page.
  window.addEventListener("dragover", function (e) { e.preventDefault(); });
  window.addEventListener("drop", function (e) { e.preventDefault(); });

  // Coming back with the Back button may restore a disabled button from the cache.
  window.addEventListener("pageshow", function () {
    setBusy(false);
    applyMode();
    refreshers.forEach(function (r) { r(); });
  });
  applyMode();
})();
