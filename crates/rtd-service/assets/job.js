// Job page for `rtd serve`: polls the job, then shows a before/after comparison and a rating form.
(function () {
  "use strict";

  var POLL_MS = 500;
  var RETRY_MS = 2000;
  var MIN_ZOOM = 1;
  var MAX_ZOOM = 8;

  function $(id) { return document.getElementById(id); }

  var parts = window.location.pathname.split("/").filter(Boolean);
  var rawKey = parts.length >= 2 && parts[0] === "jobs" ? parts[1] : "";
  var key = "";
  try { key = decodeURIComponent(rawKey); } catch (_) { key = ""; }
  var api = "/api/jobs/" + encodeURIComponent(key);

  var errorEl = $("error");
  var compare = $("compare");
  var stage = $("stage");
  var before = $("before");
  var after = $("after");
  var slider = $("slider");
  var zoomInput = $("zoom");
  var zoomValue = $("zoom-value");
  var zoom = 1;
  var shown = false;
  var lastTimings = "";

  function showError(msg) {
    errorEl.textContent = msg;
    errorEl.hidden = !msg;
  }

  function readJson(res) {
    return res.text().then(function (t) {
      try { return JSON.parse(t); } catch (_) { return null; }
    });
  }

  function errorText(body, status) {
    if (body && typeof body.error === "string" && body.error) return body.error;
    return "The server answered HTTP " + status + ".";
  }

  // ---- job status ----

  function humanise(k) {
    var s = String(k).replace(/[_-](ms|s|secs?|seconds)$/i, "").replace(/[_-]+/g, " ").replace(/\s+/g, " ").trim();
    return s.charAt(0).toUpperCase() + s.slice(1);
  }

  function formatValue(k, v) {
    if (typeof v === "number" && isFinite(v)) {
      var n = Math.abs(v) >= 100 ? v.toFixed(0) : Math.abs(v) >= 1 ? v.toFixed(2) : v.toPrecision(3);
      if (/(^|_)ms$/i.test(k)) return n + " ms";
      if (/(^|_)(s|secs?|seconds)$/i.test(k)) return n + " s";
      return n;
    }
    if (v === null || v === undefined) return "—";
    if (typeof v === "object") return JSON.stringify(v);
    return String(v);
  }

  function renderTimings(timings) {
    var section = $("timings-section");
    var json = timings ? JSON.stringify(timings) : "";
    if (json === lastTimings) return;
    lastTimings = json;
    var tbody = $("timings").tBodies[0];
    while (tbody.firstChild) tbody.removeChild(tbody.firstChild);
    var keys = timings && typeof timings === "object" ? Object.keys(timings) : [];
    keys.forEach(function (k) {
      var tr = document.createElement("tr");
      var th = document.createElement("th");
      var td = document.createElement("td");
      th.scope = "row";
      th.textContent = humanise(k);
      td.textContent = formatValue(k, timings[k]);
      tr.appendChild(th);
      tr.appendChild(td);
      tbody.appendChild(tr);
    });
    section.hidden = keys.length === 0;
  }

  function update(job) {
    var state = String(job.state || "");
    $("key").textContent = String(job.key || key);
    $("kind").textContent = String(job.kind || "—");
    $("state").textContent = state;
    $("state").setAttribute("data-state", state);
    if (job.width && job.height) $("size").textContent = job.width + " × " + job.height + " px";
    if (typeof job.created_ms === "number") {
      var d = new Date(job.created_ms);
      $("created").textContent = d.toLocaleString();
    }
    var p = Number(job.progress);
    $("progress").value = state === "done" ? 1 : isFinite(p) ? Math.min(1, Math.max(0, p)) : 0;
    document.title = "rtd — " + (job.kind ? job.kind + " job " : "job ") + state;
    renderTimings(job.timings);
    if (state === "failed") {
      showError(job.error ? String(job.error) : "The job failed.");
    } else if (state === "done") {
      showError("");
      showResult(job);
    }
  }

  function poll() {
    fetch(api, { headers: { Accept: "application/json" }, cache: "no-store" })
      .then(function (res) {
        return readJson(res).then(function (body) {
          if (res.status === 404) {
            $("state").textContent = "";
            showError("No such job.");
            return;
          }
          if (!res.ok || !body) {
            showError(errorText(body, res.status));
            setTimeout(poll, RETRY_MS);
            return;
          }
          update(body);
          if (body.state !== "done" && body.state !== "failed") setTimeout(poll, POLL_MS);
        });
      })
      .catch(function () {
        showError("Lost contact with the server; retrying…");
        setTimeout(poll, RETRY_MS);
      });
  }

  // ---- before/after comparison ----

  function setSplit(v) {
    var s = Math.min(100, Math.max(0, Number(v) || 0));
    compare.setAttribute("data-split", String(slider.value));
    compare.style.setProperty("--split", s + "%");
    after.style.clipPath = "inset(0 0 0 " + s + "%)";
    after.style.webkitClipPath = after.style.clipPath;
  }

  // Zoom about a point (ax, ay) given in pixels from the top-left of the visible area.
  function setZoom(z, ax, ay) {
    var nz = Math.min(MAX_ZOOM, Math.max(MIN_ZOOM, Number(z) || 1));
    if (ax === undefined) { ax = compare.clientWidth / 2; ay = compare.clientHeight / 2; }
    var cx = (compare.scrollLeft + ax) / zoom;
    var cy = (compare.scrollTop + ay) / zoom;
    zoom = nz;
    stage.style.transform = "scale(" + nz + ")";
    compare.style.setProperty("--zoom", String(nz));
    compare.setAttribute("data-zoom", String(nz));
    compare.classList.toggle("zoomed", nz > 1);
    compare.classList.toggle("pixelated", nz >= 2);
    zoomValue.textContent = (Math.round(nz * 100) / 100) + "×";
    if (Math.abs(Number(zoomInput.value) - nz) > 1e-6) zoomInput.value = String(nz);
    compare.scrollLeft = cx * nz - ax;
    compare.scrollTop = cy * nz - ay;
  }

  function onWheel(e) {
    e.preventDefault();
    var dy = e.deltaY * (e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? 400 : 1);
    var rect = compare.getBoundingClientRect();
    setZoom(zoom * Math.exp(-dy * 0.002), e.clientX - rect.left, e.clientY - rect.top);
  }

  function showResult(job) {
    if (shown) return;
    shown = true;
    var pending = 2;
    function loaded() {
      pending -= 1;
      if (pending === 0) compare.setAttribute("data-ready", "true");
    }
    function failed() { showError("Could not load the result images; try reloading the page."); }
    before.addEventListener("load", loaded, { once: true });
    after.addEventListener("load", loaded, { once: true });
    before.addEventListener("error", failed, { once: true });
    after.addEventListener("error", failed, { once: true });
    before.src = api + "/input.png";
    after.src = api + "/result.png";
    $("download-png").href = api + "/result.png";
    $("download-png").setAttribute("download", "rtd-" + key.slice(0, 12) + ".png");
    $("download-exr").href = api + "/result.exr";
    $("download-exr").setAttribute("download", "rtd-" + key.slice(0, 12) + ".exr");
    if (job.width > 0 && job.height > 0) {
      var ratio = job.width / job.height;
      var wrap = compare.parentNode;
      wrap.style.width = "min(100%, calc(75vh * " + ratio + "))";
      compare.style.aspectRatio = job.width + " / " + job.height;
    }
    $("result").hidden = false;
    setSplit(slider.value);
    setZoom(zoomInput.value);
    showRating(job.rating);
  }

  // ---- rating ----

  function markRated(n) {
    var form = $("rating-form");
    var msg = document.createElement("p");
    msg.id = "rated";
    msg.className = "rated";
    msg.textContent = "Thanks — rated " + n + "/5.";
    if (form) form.replaceWith(msg);
  }

  function showRating(rating) {
    $("rating-section").hidden = false;
    if (rating && rating.rating) markRated(Number(rating.rating));
  }

  function onRate(e) {
    e.preventDefault();
    var picked = document.querySelector('input[name="rating"]:checked');
    if (!picked) { showError("Choose a rating from 1 to 5."); return; }
    var n = Number(picked.value);
    var button = $("rate");
    button.disabled = true;
    showError("");
    fetch(api + "/rating", {
      method: "POST",
      headers: { "Content-Type": "application/json", Accept: "application/json" },
      body: JSON.stringify({ rating: n, comment: $("comment").value }),
    })
      .then(function (res) {
        return readJson(res).then(function (body) {
          if (res.ok) { markRated(n); return; }
          button.disabled = false;
          showError(errorText(body, res.status));
        });
      })
      .catch(function () {
        button.disabled = false;
        showError("The rating did not reach the server; try again.");
      });
  }

  // Dragging on the picture pans it when zoomed in, and moves the split otherwise.
  var drag = null;
  compare.addEventListener("pointerdown", function (e) {
    if (e.button !== 0) return;
    drag = { x: e.clientX, y: e.clientY, left: compare.scrollLeft, top: compare.scrollTop };
    compare.setPointerCapture(e.pointerId);
    onDrag(e);
  });
  function onDrag(e) {
    if (!drag) return;
    if (zoom > 1) {
      compare.scrollLeft = drag.left - (e.clientX - drag.x);
      compare.scrollTop = drag.top - (e.clientY - drag.y);
    } else {
      var rect = compare.getBoundingClientRect();
      if (rect.width <= 0) return;
      slider.value = String(Math.round((100 * (e.clientX - rect.left)) / rect.width));
      setSplit(slider.value);
    }
  }
  compare.addEventListener("pointermove", onDrag);
  compare.addEventListener("pointerup", function () { drag = null; });
  compare.addEventListener("pointercancel", function () { drag = null; });

  slider.addEventListener("input", function () { setSplit(slider.value); });
  zoomInput.addEventListener("input", function () { setZoom(zoomInput.value); });
  compare.addEventListener("wheel", onWheel, { passive: false });
  $("rating-form").addEventListener("submit", onRate);

  $("key").textContent = key;
  if (!/^[0-9a-fA-F]{1,128}$/.test(key)) {
    $("state").textContent = "";
    showError("No such job.");
  } else {
    poll();
  }
})();
