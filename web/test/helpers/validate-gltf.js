#!/usr/bin/env node
// validate-gltf.js FILE.glb...: runs the Khronos glTF-Validator (npm gltf-validator, a dev
// dependency) on each file and prints one JSON line per file with its issue counts and the
// error messages, for tests/test_gltf.py.
import { readFileSync } from 'node:fs';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file,
    maxIssues: 100,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not allowed')),
  });
  const errors = report.issues.messages.filter((m) => m.severity === 0).map((m) => `${m.code} ${m.pointer ?? ''}: ${m.message}`);
  console.log(JSON.stringify({
    file,
    errors: report.issues.numErrors,
    warnings: report.issues.numWarnings,
    messages: errors,
    info: report.info,
  }));
}
