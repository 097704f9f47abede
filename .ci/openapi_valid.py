#!/usr/bin/env python3
"""Validates openapi.yaml against the OpenAPI 3.0 schema with openapi-spec-validator
(a real validator, not a YAML parse): 3.1-only keywords in the 3.0.3 document, keys that a
stray `, mm` in a flow mapping creates, and wrong types all fail. Prints every error."""
import sys

from openapi_spec_validator import OpenAPIV30SpecValidator
from openapi_spec_validator.readers import read_from_filename

path = sys.argv[1] if len(sys.argv) > 1 else "openapi.yaml"
spec, _ = read_from_filename(path)
if spec.get("openapi", "").split(".")[:2] != ["3", "0"]:
    sys.exit(f"{path}: expected an OpenAPI 3.0 document, found {spec.get('openapi')!r}")
errors = list(OpenAPIV30SpecValidator(spec).iter_errors())
for e in errors:
    where = "/".join(str(p) for p in e.absolute_path)
    print(f"{path}: {where}: {e.message[:300]}")
if errors:
    sys.exit(f"{path}: {len(errors)} error(s)")
print(f"{path}: valid OpenAPI {spec['openapi']} ({len(spec['paths'])} paths)")
