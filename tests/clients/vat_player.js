// Plays springbake's vertex animation textures in headless Chromium with three.js (the page in
// tests/clients/vat_player/) and compares them with three.js's own playback of the glTF morph
// cache (and of the pca cache) of the same bake.
//
// Usage: node vat_player.js BAKE_FOLDER OUT.vat MORPH.glb [PCA.glb] FRAME...
// BAKE_FOLDER is served as /bake/; OUT.vat, MORPH.glb and PCA.glb are names inside it ("-" for
// no pca). Prints one JSON line: per frame, each player's silhouette IoU and mean colour
// difference against the morph cache. Writes BAKE_FOLDER/vat_player.png, the page's last image.
const http = require("http");
const fs = require("fs");
const path = require("path");
const { chromium } = require("playwright-core");

const root = path.resolve(__dirname, "../..");
const [bakeFolder, vat, morph, pca, ...frames] = process.argv.slice(2);
const types = { ".html": "text/html", ".js": "text/javascript", ".json": "application/json",
  ".glb": "model/gltf-binary", ".png": "image/png", ".exr": "application/octet-stream" };

function resolveUrl(url) {
  const clean = decodeURIComponent(url.split("?")[0]);
  const inside = (base, rest) => {
    const file = path.resolve(base, "." + rest);
    return file.startsWith(path.resolve(base) + path.sep) ? file : null;
  };
  if (clean === "/" || clean === "/index.html") return path.join(__dirname, "vat_player/index.html");
  if (clean.startsWith("/player/")) return inside(path.join(__dirname, "vat_player"), clean.slice(7));
  if (clean.startsWith("/node_modules/")) return inside(path.join(root, "node_modules"), clean.slice(13));
  if (clean.startsWith("/bake/")) return inside(bakeFolder, clean.slice(5));
  return null;
}

const server = http.createServer((req, res) => {
  if (req.url === "/favicon.ico") {
    res.writeHead(204);
    res.end();
    return;
  }
  const file = resolveUrl(req.url);
  if (!file || !fs.existsSync(file) || fs.statSync(file).isDirectory()) {
    res.writeHead(404);
    res.end();
    return;
  }
  res.writeHead(200, { "Content-Type": types[path.extname(file)] || "application/octet-stream" });
  fs.createReadStream(file).pipe(res);
});

async function main() {
  await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
  const port = server.address().port;
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    args: ["--headless", "--no-sandbox", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  try {
    const page = await browser.newPage({ viewport: { width: 512, height: 512 } });
    const errors = [];
    page.on("pageerror", (e) => errors.push(String(e)));
    page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
    await page.goto(`http://127.0.0.1:${port}/`);
    await page.waitForFunction(() => window.ready === true || false, null, { timeout: 60000 })
      .catch(() => { throw new Error("the player did not load: " + errors.join("; ")); });
    const results = await page.evaluate((spec) => window.compare(spec), {
      vat: `/bake/${vat}`,
      morph: `/bake/${morph}`,
      pca: pca === "-" ? null : `/bake/${pca}`,
      frames: frames.map(Number),
    });
    await page.locator("#view").screenshot({ path: path.join(bakeFolder, "vat_player.png") });
    console.log(JSON.stringify({ results, errors }));
  } finally {
    await browser.close();
    server.close();
  }
}

main().catch((e) => { console.error(e.stack || String(e)); server.close(); process.exit(1); });
