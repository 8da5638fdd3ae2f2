#!/usr/bin/env node
// Validate glTF files with the Khronos glTF validator (npm `gltf-validator`): exits 1 when
// any file has an error or a warning, printing every message.
//
//   NODE_PATH=<folder holding node_modules> node scripts/gltf/validate.js A.gltf [B.gltf …]
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function main(files) {
  if (files.length === 0) {
    console.error('usage: validate.js FILE.gltf…');
    return 2;
  }
  let failed = 0;
  for (const file of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: path.basename(file),
      maxIssues: 100,
    });
    const { numErrors, numWarnings, numInfos } = report.issues;
    for (const m of report.issues.messages) {
      console.log(`${file}: ${['error', 'warning', 'info', 'hint'][m.severity]} ${m.code} ${m.pointer || ''}: ${m.message}`);
    }
    console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos (validator ${report.validatorVersion})`);
    if (numErrors > 0 || numWarnings > 0) failed += 1;
  }
  return failed === 0 ? 0 : 1;
}

main(process.argv.slice(2)).then((code) => process.exit(code), (e) => {
  console.error(e);
  process.exit(2);
});
