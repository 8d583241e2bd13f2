// Runs the Khronos glTF validator over .glb files.
//
//   node checks/gltf/validate.mjs FILE.glb...
//
// Prints one line per file ("path: N errors, M warnings, K infos"), followed by
// the errors and warnings if any, and exits 1 if any file has errors, cannot be
// read, or no file was given. Part of the project; MIT OR Apache-2.0.
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error("usage: node checks/gltf/validate.mjs FILE.glb...");
  process.exit(1);
}

let failed = false;
for (const file of files) {
  let report;
  try {
    const bytes = new Uint8Array(await readFile(file));
    report = await validator.validateBytes(bytes, {
      uri: file,
      maxIssues: 100,
      // Our files are self-contained: refuse any external resource.
      externalResourceFunction: (uri) =>
        Promise.reject(new Error(`external resource not allowed: ${uri}`)),
    });
  } catch (err) {
    console.log(`${file}: cannot validate: ${err && err.message ? err.message : err}`);
    failed = true;
    continue;
  }
  const { numErrors, numWarnings, numInfos, messages } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  for (const m of messages) {
    // Errors and warnings by name; infos (such as unused data) counted only.
    if (m.severity <= 1) {
      const kind = m.severity === 0 ? "error" : "warning";
      console.log(`  ${kind} ${m.code} at ${m.pointer ?? "?"}: ${m.message}`);
    }
  }
  if (numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
