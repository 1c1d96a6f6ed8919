// Validate a glTF file with the Khronos glTF validator; prints the report's JSON on stdout.
// usage: node validate.mjs FILE.gltf   (exit 0 when it ran, whatever the issues; 2 on bad usage)
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

const file = process.argv[2];
if (!file) {
  console.error('usage: node validate.mjs FILE.gltf');
  process.exit(2);
}
const data = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(data, {
  uri: path.basename(file),
  maxIssues: 100,
  externalResourceFunction: async (uri) =>
    new Uint8Array(await readFile(path.join(path.dirname(file), decodeURIComponent(uri)))),
});
process.stdout.write(JSON.stringify(report, null, 1) + '\n');
