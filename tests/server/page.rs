//! The page in a real browser: headless Chromium, driven over the W3C WebDriver protocol by
//! chromedriver, against the real binary. A photograph is uploaded, the detected circle is
//! checked and corrected with the keyboard and the pointer, a white card is outlined, the
//! answer is read off the page; a non-image shows the problem's title and detail; the page
//! fits a phone's width; `/docs` renders the served OpenAPI document.
//!
//! Needs Debian's `chromium` and `chromium-driver` (`.ci/run` installs them). Without them the
//! test is marked ignored, with the reason in the summary (`build.rs` decides at build time
//! and notices their installation by itself: the next `cargo test` runs it), unless
//! `REFLECTANCE_REQUIRE_BROWSER=1` (set by `.ci/run`), with which it runs and fails if they
//! are missing.
//! `REFLECTANCE_UPDATE_SCREENSHOT=1` rewrites `docs/page.jpg` from the run.

use crate::common;
use crate::faults::{Reply, Server, exchange, setup, spawn, wait_until};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// The W3C name of an element reference in WebDriver answers.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

fn find_program(env: &str, candidates: &[&str]) -> Option<PathBuf> {
    if let Some(path) = std::env::var_os(env) {
        return Some(PathBuf::from(path));
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    candidates.iter().find_map(|name| {
        std::env::split_paths(&path)
            .map(|dir| dir.join(name))
            .find(|p| p.is_file())
    })
}

/// A browser session through chromedriver.
struct Browser {
    driver: Child,
    port: u16,
    session: String,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let path = format!("/session/{}", self.session);
        let _ = exchange(
            self.port,
            "DELETE",
            &path,
            "application/json",
            b"",
            secs(10),
        );
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

fn secs(s: u64) -> Duration {
    Duration::from_secs(s)
}

fn webdriver(port: u16, method: &str, path: &str, body: &Value) -> Value {
    let bytes = serde_json::to_vec(body).unwrap();
    let reply: Reply = exchange(port, method, path, "application/json", &bytes, secs(60))
        .unwrap_or_else(|| panic!("chromedriver: no answer to {method} {path}"));
    let answer = reply.json();
    assert_eq!(
        reply.status,
        200,
        "{method} {path}: {}",
        String::from_utf8_lossy(&reply.body)
    );
    answer["value"].clone()
}

impl Browser {
    /// A headless Chromium of `width` × `height` CSS pixels, or `None` when not installed.
    fn start(width: u32, height: u32) -> Option<Browser> {
        let driver = find_program("REFLECTANCE_CHROMEDRIVER", &["chromedriver"])?;
        let chromium = find_program("REFLECTANCE_CHROMIUM", &["chromium", "chromium-browser"])?;
        let port = common::server::free_port();
        let child = Command::new(driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .ok()?;
        let mut browser = Browser {
            driver: child,
            port,
            session: String::new(),
        };
        wait_until(secs(30), "chromedriver", || {
            exchange(port, "GET", "/status", "application/json", b"", secs(2))
                .is_some_and(|r| r.json()["value"]["ready"] == true)
        });
        let options = json!({
            "binary": chromium,
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                     "--disable-dev-shm-usage", format!("--window-size={width},{height}")],
        });
        let capabilities = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome", "goog:chromeOptions": options}}});
        let session = webdriver(port, "POST", "/session", &capabilities);
        browser.session = session["sessionId"].as_str().unwrap().to_string();
        Some(browser)
    }

    fn call(&self, method: &str, path: &str, body: Value) -> Value {
        let path = format!("/session/{}{path}", self.session);
        webdriver(self.port, method, &path, &body)
    }

    fn open(&self, url: &str) {
        self.call("POST", "/url", json!({ "url": url }));
    }

    fn find(&self, css: &str) -> String {
        let found = self.call(
            "POST",
            "/element",
            json!({"using": "css selector", "value": css}),
        );
        found[ELEMENT]
            .as_str()
            .unwrap_or_else(|| panic!("{css}: {found}"))
            .to_string()
    }

    fn script(&self, body: &str) -> Value {
        self.call("POST", "/execute/sync", json!({"script": body, "args": []}))
    }

    /// Poll `expression` until it is truthy; its value.
    fn wait_for(&self, what: &str, expression: &str) -> Value {
        let mut value = Value::Null;
        wait_until(secs(60), what, || {
            value = self.script(&format!("return {expression};"));
            !matches!(&value, Value::Null | Value::Bool(false))
                && value != json!("")
                && value != json!(0)
        });
        value
    }

    /// Click the element `css` selects.
    fn click(&self, css: &str) {
        let element = self.find(css);
        self.call("POST", &format!("/element/{element}/click"), json!({}));
    }

    fn number(&self, id: &str) -> f64 {
        let value = self.script(&format!("return document.getElementById('{id}').value;"));
        value.as_str().and_then(|v| v.parse().ok()).unwrap()
    }

    fn upload(&self, file: &Path) {
        self.upload_to("#file", file);
    }

    fn upload_to(&self, css: &str, file: &Path) {
        let input = self.find(css);
        let text = file.to_str().unwrap();
        self.call(
            "POST",
            &format!("/element/{input}/value"),
            json!({ "text": text }),
        );
    }

    fn keys(&self, keys: &str) {
        let actions: Vec<Value> = keys
            .chars()
            .flat_map(|k| {
                let k = k.to_string();
                [
                    json!({"type": "keyDown", "value": k}),
                    json!({"type": "keyUp", "value": k}),
                ]
            })
            .collect();
        self.call(
            "POST",
            "/actions",
            json!({"actions": [{"type": "key", "id": "keyboard", "actions": actions}]}),
        );
    }

    /// Press at `from`, move to `to`, release (viewport CSS pixels).
    fn drag(&self, from: (f64, f64), to: (f64, f64)) {
        let at = |(x, y): (f64, f64)| {
            json!({"type": "pointerMove", "origin": "viewport", "x": x.round() as i64,
                   "y": y.round() as i64, "duration": 50})
        };
        let actions = json!([
            at(from),
            {"type": "pointerDown", "button": 0},
            at(((from.0 + to.0) / 2.0, (from.1 + to.1) / 2.0)),
            at(to),
            {"type": "pointerUp", "button": 0},
        ]);
        self.call(
            "POST",
            "/actions",
            json!({"actions": [{"type": "pointer", "id": "mouse",
                   "parameters": {"pointerType": "mouse"}, "actions": actions}]}),
        );
        self.call("DELETE", "/actions", json!({}));
    }

    /// Viewport CSS pixels of an image pixel of the photograph on the canvas.
    fn on_canvas(&self, x: f64, y: f64, image_width: f64) -> (f64, f64) {
        let b = self.script(
            "const b = document.getElementById('canvas').getBoundingClientRect(); \
             return [b.left, b.top, b.width];",
        );
        let (left, top, width) = (
            b[0].as_f64().unwrap(),
            b[1].as_f64().unwrap(),
            b[2].as_f64().unwrap(),
        );
        let scale = width / image_width;
        (left + (x + 0.5) * scale, top + (y + 0.5) * scale)
    }

    fn screenshot(&self) -> Vec<u8> {
        use base64::Engine;
        let png = self.call("GET", "/screenshot", json!({}));
        base64::engine::general_purpose::STANDARD
            .decode(png.as_str().unwrap())
            .unwrap()
    }
}

/// The fixture: a 1280 × 960 JPEG of a white_shiny Ward sphere (ρd 0.7, ρs 0.25, α 0.01)
/// rendered under ict_pisa (not a training probe), centre (699.5, 469.5), radius 290.9,
/// beside a white card of reflectance 0.9 at x 80–300, y 620–800; white exposed to 0.8.
const PHOTO: &str = "tests/fixtures/page/phone.jpg";
const PHOTO_WIDTH: f64 = 1280.0;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn browser_or_skip(width: u32, height: u32) -> Option<Browser> {
    let browser = Browser::start(width, height);
    if browser.is_none() {
        assert!(
            std::env::var_os("REFLECTANCE_REQUIRE_BROWSER").is_none(),
            "REFLECTANCE_REQUIRE_BROWSER is set but chromium or chromedriver is missing"
        );
        eprintln!("skipped: needs chromium and chromedriver (Debian: chromium chromium-driver)");
    }
    browser
}

/// Upload `file` and check the detected circle against `expected` (within 3 px); its
/// (cx, cy, r).
fn upload_and_detect(browser: &Browser, file: &Path, expected: (f64, f64, f64)) -> (f64, f64, f64) {
    browser.upload(file);
    browser.wait_for(
        "the circle",
        "!document.getElementById('stage').hidden && document.getElementById('r').value",
    );
    let (cx, cy, r) = (
        browser.number("cx"),
        browser.number("cy"),
        browser.number("r"),
    );
    let (ex, ey, er) = expected;
    assert!(
        (cx - ex).abs() < 3.0 && (cy - ey).abs() < 3.0 && (r - er).abs() < 3.0,
        "detected ({cx}, {cy}, {r})"
    );
    (cx, cy, r)
}

fn adjust_the_circle(browser: &Browser, (cx, r): (f64, f64)) {
    // The keyboard: 3 px right, radius 2 px larger.
    browser.script("document.getElementById('canvas').focus();");
    browser.keys("\u{E014}\u{E014}\u{E014}++");
    assert!((browser.number("cx") - (cx + 3.0)).abs() < 0.051);
    let grown = browser.number("r");
    assert!((grown - (r + 2.0)).abs() < 0.051, "radius {r} → {grown}");
    // The pointer: the rim handle dragged 40 image pixels outwards, then the centre back.
    let (cx, cy, r) = (
        browser.number("cx"),
        browser.number("cy"),
        browser.number("r"),
    );
    let rim = browser.on_canvas(cx + r, cy, PHOTO_WIDTH);
    let out = browser.on_canvas(cx + r + 40.0, cy, PHOTO_WIDTH);
    browser.drag(rim, out);
    let dragged = browser.number("r");
    assert!(
        (dragged - (r + 40.0)).abs() < 3.0,
        "radius {r} dragged to {dragged}"
    );
    browser.drag(
        browser.on_canvas(cx, cy, PHOTO_WIDTH),
        browser.on_canvas(cx - 3.0, cy, PHOTO_WIDTH),
    );
    assert!((browser.number("cx") - (cx - 3.0)).abs() < 2.0);
    // Back to the detected radius for the classification.
    browser.drag(out, rim);
    assert!((browser.number("r") - r).abs() < 3.0);
}

/// Whether the card's reflectance field is shown (it is only with a white card).
fn card_reflectance_shown(browser: &Browser) -> bool {
    browser
        .script("return document.getElementById('white-reflectance').getClientRects().length > 0;")
        .as_bool()
        .unwrap()
}

fn outline_the_white_card(browser: &Browser) {
    browser.find("input[name='white-mode'][value='rect']");
    assert!(
        !card_reflectance_shown(browser),
        "the card's reflectance is shown without a card"
    );
    browser.script(
        "const radio = document.querySelector(\"input[name='white-mode'][value='rect']\"); \
         radio.click();",
    );
    assert!(
        card_reflectance_shown(browser),
        "the card's reflectance is hidden"
    );
    browser.drag(
        browser.on_canvas(100.0, 640.0, PHOTO_WIDTH),
        browser.on_canvas(280.0, 780.0, PHOTO_WIDTH),
    );
    let rect = browser.script("return document.getElementById('white-rect').value;");
    let rect: Vec<f64> = rect
        .as_str()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    let expected = [100.0, 640.0, 180.0, 140.0];
    for (got, want) in rect.iter().zip(expected) {
        assert!(
            (got - want).abs() < 4.0,
            "rectangle {rect:?}, expected ≈ {expected:?}"
        );
    }
    browser.script("const r = document.getElementById('white-reflectance'); r.value = '0.9';");
}

fn classify_and_read_the_answer(browser: &Browser) {
    browser.click("#classify");
    let label = browser.wait_for(
        "the answer",
        "!document.getElementById('result').hidden && document.getElementById('label').textContent",
    );
    assert_eq!(label, "white_shiny");
    let bars = browser.script(
        "return [...document.querySelectorAll('#bars li')].map(li => li.getAttribute('aria-label'));",
    );
    let bars: Vec<&str> = bars
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(bars.len(), 6, "{bars:?}");
    assert!(bars[0].starts_with("white_shiny: "), "{bars:?}");
    let total: f64 = bars
        .iter()
        .map(|b| {
            b.rsplit(": ")
                .next()
                .unwrap()
                .trim_end_matches(" %")
                .parse::<f64>()
                .unwrap()
        })
        .sum();
    assert!((total - 100.0).abs() < 0.5, "{bars:?}");
    browser.wait_for(
        "the rendered class",
        "document.getElementById('rendered').complete && document.getElementById('rendered').naturalWidth",
    );
    let shown = browser.script(
        "const loaded = (img) => img.complete && img.naturalWidth > 0; \
         return { annulus: loaded(document.getElementById('annulus')), \
                  subbands: [...document.querySelectorAll('#subbands img')].filter(loaded).length, \
                  neighbours: document.querySelectorAll('#neighbours li').length, \
                  thumbnails: [...document.querySelectorAll('#neighbours img')].filter(loaded).length, \
                  rendered: loaded(document.getElementById('rendered')), \
                  description: document.getElementById('description').textContent, \
                  ward: document.getElementById('ward').textContent };",
    );
    assert_eq!(shown["annulus"], true, "{shown}");
    assert_eq!(shown["rendered"], true, "{shown}");
    assert_eq!(shown["subbands"].as_u64().unwrap() % 3, 0, "{shown}");
    assert!(shown["subbands"].as_u64().unwrap() >= 9, "{shown}");
    assert_eq!(shown["neighbours"], 3, "{shown}");
    assert_eq!(shown["thumbnails"], 3, "{shown}");
    assert!(
        shown["ward"].as_str().unwrap().contains("ρs = 0.25"),
        "{shown}"
    );
    // The headline names the class once (its description, "white shiny", adds nothing).
    assert!(
        !shown["description"]
            .as_str()
            .unwrap()
            .starts_with("white shiny"),
        "{shown}"
    );
    // The prediction set as chips, the label first; a photograph of a sphere is in domain.
    let honest = browser.script(
        "return { chips: [...document.querySelectorAll('#set li')].map(li => li.textContent), \
                  set_shown: !document.getElementById('set-box').hidden, \
                  banner: !document.getElementById('domain-box').hidden };",
    );
    assert_eq!(honest["set_shown"], true, "{honest}");
    assert_eq!(honest["chips"][0], "white_shiny", "{honest}");
    assert_eq!(honest["banner"], false, "{honest}");
    // The download for a renderer: a glTF asset of the parameters shown.
    browser.script(
        "window.gltfAsset = null; \
         fetch(document.getElementById('gltf').href).then(r => r.json()) \
           .then(j => { window.gltfAsset = j.asset.version + ' ' + j.materials[0].name; });",
    );
    let asset = browser.wait_for("the glTF download", "window.gltfAsset");
    assert_eq!(asset, "2.0 estimate", "{asset}");
    // The nearest images' captions do not run into each other.
    let overlaps = browser.script(
        "const boxes = [...document.querySelectorAll('#neighbours li')].map(li => li.getBoundingClientRect()); \
         let n = 0; \
         for (let i = 0; i < boxes.length; i++) for (let j = i + 1; j < boxes.length; j++) { \
           const a = boxes[i], b = boxes[j]; \
           if (a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom) n++; } \
         const spill = [...document.querySelectorAll('#neighbours li')] \
           .filter(li => li.scrollWidth > li.clientWidth + 1).length; \
         return n + spill;",
    );
    assert_eq!(overlaps, 0, "captions overlap or spill out of their box");
}

/// The page's own icon loads (no request for a missing /favicon.ico), and the model menu
/// shows whole names.
fn the_icon_loads_and_the_model_names_are_whole(browser: &Browser) {
    let icon = browser.wait_for(
        "the icon",
        "(() => { const link = document.querySelector('link[rel=icon]'); \
         if (!link) return 'missing'; \
         if (!window.__icon) { window.__icon = new Image(); window.__icon.src = link.href; } \
         return window.__icon.complete && (window.__icon.naturalWidth > 0 ? 'loaded' : 'broken'); })()",
    );
    assert_eq!(icon, "loaded");
    let menu = browser.script(
        "const s = document.getElementById('model'); \
         return { whole: s.scrollWidth <= s.clientWidth + 1, \
                  options: [...s.options].map(o => o.textContent) };",
    );
    assert_eq!(menu["whole"], true, "{menu}");
    assert!(
        menu["options"][0].as_str().unwrap().ends_with("classes)"),
        "{menu}"
    );
}

fn a_non_image_shows_the_problem(browser: &Browser) {
    browser.upload(&root().join("Cargo.toml"));
    let title = browser.wait_for(
        "the error",
        "!document.getElementById('error').hidden && document.getElementById('error-title').textContent",
    );
    assert_eq!(title, "Unsupported image format");
    let detail = browser.script("return document.getElementById('error-detail').textContent;");
    let detail = detail.as_str().unwrap();
    assert!(detail.contains("expected PNG, JPEG"), "{detail}");
    // The title is not said twice.
    assert!(
        !detail
            .to_lowercase()
            .starts_with("unsupported image format"),
        "{detail}"
    );
}

/// The screenshot in `target/`, and at two thirds of its size in the docs when asked.
fn keep_the_screenshot(png: &[u8]) {
    std::fs::write(root().join("target/page-screenshot.png"), png).unwrap();
    let shot = image::load_from_memory(png).unwrap();
    assert!(shot.width() >= 1000, "{} px wide", shot.width());
    if std::env::var_os("REFLECTANCE_UPDATE_SCREENSHOT").is_some() {
        let (w, h) = (shot.width() * 2 / 3, shot.height() * 2 / 3);
        let small = shot.resize(w, h, image::imageops::FilterType::Triangle);
        small.to_rgb8().save(root().join("docs/page.jpg")).unwrap();
    }
}

#[cfg_attr(
    not(browser),
    ignore = "needs chromium and chromedriver (Debian: chromium chromium-driver)"
)]
#[test]
fn the_page_classifies_a_photograph_in_a_real_browser() {
    let Some(browser) = browser_or_skip(1280, 1180) else {
        return;
    };
    let base = setup("page");
    let server: Server = spawn(&base, None);
    let page = format!("http://127.0.0.1:{}/", server.port);
    browser.open(&page);
    browser.wait_for(
        "the models",
        "document.querySelectorAll('#model option').length",
    );
    let (cx, _, r) = upload_and_detect(&browser, &root().join(PHOTO), (699.5, 469.5, 290.9));
    the_circle_to_check_is_on_screen(&browser);
    adjust_the_circle(&browser, (cx, r));
    outline_the_white_card(&browser);
    classify_and_read_the_answer(&browser);
    the_icon_loads_and_the_model_names_are_whole(&browser);
    browser.script("window.scrollTo(0, 0);");
    keep_the_screenshot(&browser.screenshot());
    a_non_image_shows_the_problem(&browser);
    an_object_shows_its_equivalent_sphere(&browser, &base);
    a_small_ball_is_zoomed_to(&browser, &base);

    // A phone's width: nothing wider than the screen.
    browser.call("POST", "/window/rect", json!({"width": 390, "height": 844}));
    browser.open(&page);
    // The example photograph, one tap: the same render as the fixture.
    browser.click("[data-name='white-shiny-ball.jpg']");
    browser.wait_for(
        "the example's circle",
        "!document.getElementById('stage').hidden && document.getElementById('r').value",
    );
    assert!((browser.number("r") - 290.9).abs() < 3.0);
    the_circle_to_check_is_on_screen(&browser);
    classify_and_read_the_answer_on_a_phone(&browser);
    without_white_the_page_says_it_once(&browser);
    the_icon_loads_and_the_model_names_are_whole(&browser);
    an_error_replaces_the_answer(&browser);

    // The API reference, rendered offline by the vendored viewer.
    browser.open(&format!("http://127.0.0.1:{}/docs", server.port));
    let title = browser.wait_for(
        "Swagger UI",
        "document.querySelector('.swagger-ui .info .title')?.textContent",
    );
    assert!(
        title.as_str().unwrap().starts_with("reflectance"),
        "{title}"
    );
    let operations = browser.wait_for(
        "the operations",
        "document.querySelectorAll('.opblock').length",
    );
    assert!(operations.as_u64().unwrap() >= 20, "{operations}");
}

/// A torus and its normal map: classified as its equivalent sphere, shown beside the
/// annulus.
fn an_object_shows_its_equivalent_sphere(browser: &Browser, dir: &Path) {
    let (image, normals, _, _) = super::shapes::held_out_tori().swap_remove(1);
    let (image_path, normals_path) = (dir.join("torus.pfm"), dir.join("torus.normals.png"));
    std::fs::write(&image_path, image).unwrap();
    std::fs::write(&normals_path, normals).unwrap();
    browser.upload(&image_path);
    browser.wait_for(
        "the photograph",
        "!document.getElementById('stage').hidden && document.getElementById('r').value",
    );
    browser.upload_to("#normals", &normals_path);
    browser.click("#classify");
    let outcome = browser.wait_for(
        "the equivalent sphere",
        "(!document.getElementById('error').hidden \
          && document.getElementById('error-detail').textContent) \
         || (!document.getElementById('result').hidden \
             && !document.getElementById('equivalent-figure').hidden \
             && document.getElementById('equivalent').complete \
             && document.getElementById('equivalent').naturalWidth)",
    );
    assert!(outcome.is_number(), "{outcome}");
    let label = browser.script("return document.getElementById('label').textContent;");
    assert!(!label.as_str().unwrap().is_empty(), "{label}");
    let read_by =
        browser.script("return document.getElementById('equivalent-classifier').textContent;");
    assert!(
        read_by
            .as_str()
            .unwrap()
            .starts_with("Read by the model's classifier"),
        "{read_by}"
    );
}

/// The fixture a quarter of its size in a 2048 × 1536 grey scene: a ball of radius 72.7 px
/// (about 90 CSS pixels across on a 1280 px window), its centre near (1574.6, 417.4).
fn write_small_ball(dir: &Path) -> PathBuf {
    let photo = image::open(root().join(PHOTO)).unwrap().to_rgb8();
    let small = image::imageops::resize(&photo, 320, 240, image::imageops::FilterType::Triangle);
    let mut scene = image::RgbImage::from_pixel(2048, 1536, image::Rgb([90, 90, 90]));
    image::imageops::overlay(&mut scene, &small, 1400, 300);
    let path = dir.join("small-ball.png");
    scene.save(&path).unwrap();
    path
}

/// A small ball is shown zoomed to its circle: drawn large, its rim handle dragged by the
/// pointer moves the rim by the image pixels the zoomed picture shows; the button goes back
/// to the whole photograph.
fn a_small_ball_is_zoomed_to(browser: &Browser, dir: &Path) {
    let (cx, cy, r) = upload_and_detect(browser, &write_small_ball(dir), (1574.6, 417.4, 72.7));
    let pressed =
        browser.script("return document.getElementById('zoom').getAttribute('aria-pressed');");
    assert_eq!(pressed, "true", "a small ball is not zoomed to");
    let status = browser.script("return document.getElementById('status').textContent;");
    assert!(status.as_str().unwrap().contains("Zoomed"), "{status}");
    // Viewport CSS pixels of an image point, through the zoomed view.
    let at = |x: f64, y: f64| {
        let m = browser.script(
            "const b = document.getElementById('canvas').getBoundingClientRect();              const v = state.view; return [b.left, b.top, b.width / v.w, v.x, v.y];",
        );
        let m: Vec<f64> = m
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        (
            m[0] + (x + 0.5 - m[3]) * m[2],
            m[1] + (y + 0.5 - m[4]) * m[2],
        )
    };
    let (left, _) = at(cx - r, cy);
    let (right, _) = at(cx + r, cy);
    assert!(
        right - left > 250.0,
        "the circle is {} CSS px across",
        right - left
    );
    browser.drag(at(cx + r, cy), at(cx + r + 10.0, cy));
    let grown = browser.number("r");
    assert!(
        (grown - (r + 10.0)).abs() < 1.0,
        "radius {r} dragged to {grown}"
    );
    browser.click("#zoom");
    let whole = browser.script(
        "return [state.view, document.getElementById('zoom').getAttribute('aria-pressed')];",
    );
    assert_eq!(
        whole,
        json!([null, "false"]),
        "the whole photograph is not shown"
    );
}

/// Without a white reference: the estimate's table lists what it states, the note says
/// once why ρd and ρs are not there, and no empty colour swatch shows.
fn without_white_the_page_says_it_once(browser: &Browser) {
    let shown = browser.script(
        "return { rows: [...document.querySelectorAll('#estimate th')].map(th => th.textContent), \
                  table: document.getElementById('estimate').textContent, \
                  note: document.getElementById('estimate-note').textContent, \
                  swatch: document.getElementById('swatch').getClientRects().length };",
    );
    let rows: Vec<&str> = shown["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(
        rows.iter()
            .all(|r| !r.starts_with("ρd") && !r.starts_with("ρs (")),
        "{shown}"
    );
    assert!(rows.iter().any(|r| r.starts_with("α")), "{shown}");
    assert!(
        !shown["table"].as_str().unwrap().contains("unknown"),
        "{shown}"
    );
    assert!(shown["note"].as_str().unwrap().contains("white"), "{shown}");
    assert_eq!(shown["swatch"], 0, "an empty swatch shows: {shown}");
}

/// Whether element `id` shows at least partly inside the window.
fn on_screen(browser: &Browser, id: &str) -> bool {
    browser
        .script(&format!(
            "const b = document.getElementById('{id}').getBoundingClientRect(); \
             return b.bottom > 0 && b.top < window.innerHeight && b.height > 0;"
        ))
        .as_bool()
        .unwrap()
}

/// After detection the status and the circle it asks to check are on screen.
fn the_circle_to_check_is_on_screen(browser: &Browser) {
    assert!(on_screen(browser, "status"), "the status is off screen");
    assert!(on_screen(browser, "canvas"), "the picture is off screen");
}

/// An error after an answer: the error on screen, the stale answer gone; and the circle
/// posted as the page holds it, not as its inputs round it.
fn an_error_replaces_the_answer(browser: &Browser) {
    browser.script(
        "document.querySelector(\"input[name='white-mode'][value='value']\").click(); \
         document.getElementById('white-value').value = '0'; \
         window.posted = null; \
         const fetched = window.fetch; \
         window.fetch = (url, options) => { \
           if (options && options.body instanceof FormData && options.body.has('cx')) { \
             window.posted = ['cx', 'cy', 'r'].map(k => options.body.get(k)); } \
           return fetched(url, options); };",
    );
    browser.script("window.scrollTo(0, 0);");
    browser.click("#classify");
    browser.wait_for(
        "the error",
        "!document.getElementById('error').hidden && document.getElementById('error-title').textContent",
    );
    assert!(on_screen(browser, "error"), "the error is off screen");
    let stale = browser.script("return document.getElementById('result').hidden;");
    assert_eq!(stale, true, "the previous answer stays beside the error");
    let posted = browser.script(
        "return [window.posted, [state.circle.cx, state.circle.cy, state.circle.r].map(String)];",
    );
    assert_eq!(posted[0], posted[1], "the circle posted is not the page's");
}

fn classify_and_read_the_answer_on_a_phone(browser: &Browser) {
    browser.click("#classify");
    browser.wait_for(
        "the answer",
        "!document.getElementById('result').hidden && document.getElementById('label').textContent",
    );
    let overflow = browser.script(
        "const width = document.documentElement.clientWidth; \
         return [...document.querySelectorAll('body *')] \
           .filter(e => e.getBoundingClientRect().right > width + 0.5) \
           .map(e => `${e.tagName}#${e.id}.${e.className}`);",
    );
    assert_eq!(overflow, json!([]), "wider than a phone's screen");
    // Every class name whole, on one line: not cut, not broken.
    let cut = browser.script(
        "return [...document.querySelectorAll('#bars .name')].filter(e => { \
           const range = document.createRange(); range.selectNodeContents(e); \
           return e.scrollWidth > e.clientWidth + 0.5 || range.getClientRects().length !== 1; \
         }).map(e => e.textContent);",
    );
    assert_eq!(cut, json!([]), "class names cut on a phone");
    assert!(
        !card_reflectance_shown(browser),
        "the card's reflectance is shown with the white reference \"none\""
    );
}
