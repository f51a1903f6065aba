// Validates deploy/k8s/*.yaml against the Kubernetes OpenAPI schemas with the
// kubernetes-models package (needs npm's registry, which CI does not reach):
//   npm install kubernetes-models@4 yaml@2 && node deploy/k8s/validate.mjs deploy/k8s/gvd.yaml
import { readFileSync } from "node:fs";
import { parseAllDocuments } from "yaml";

const kinds = {
  "v1/PersistentVolumeClaim": "kubernetes-models/v1/PersistentVolumeClaim",
  "v1/Service": "kubernetes-models/v1/Service",
  "apps/v1/Deployment": "kubernetes-models/apps/v1/Deployment",
  "apps/v1/StatefulSet": "kubernetes-models/apps/v1/StatefulSet",
  "v1/Secret": "kubernetes-models/v1/Secret",
};
let count = 0;
for (const path of process.argv.slice(2)) {
  for (const doc of parseAllDocuments(readFileSync(path, "utf8"))) {
    const obj = doc.toJS();
    if (!obj) continue;
    const module = kinds[`${obj.apiVersion}/${obj.kind}`];
    if (!module) throw new Error(`${path}: no schema for ${obj.apiVersion} ${obj.kind}`);
    const Model = (await import(module))[obj.kind];
    new Model(obj).validate();  // throws with the schema violation
    console.log(`${path}: ${obj.kind} ${obj.metadata.name} is valid`);
    count++;
  }
}
console.log(`${count} manifests valid`);
