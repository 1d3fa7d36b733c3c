// Validates one .gltf/.glb with the Khronos gltf-validator and prints the JSON report.
// Usage: node tests/clients/validate_gltf.js FILE
const fs = require('fs');
const path = require('path');
const validator = require(path.join(process.cwd(), 'node_modules', 'gltf-validator'));

const file = process.argv[2];
const bytes = new Uint8Array(fs.readFileSync(file));
const dir = path.dirname(file);
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        try {
          resolve(new Uint8Array(fs.readFileSync(path.join(dir, decodeURIComponent(uri)))));
        } catch (e) {
          reject(e.toString());
        }
      }),
  })
  .then((report) => {
    process.stdout.write(JSON.stringify(report));
  })
  .catch((e) => {
    console.error('validator failed:', e);
    process.exit(1);
  });
