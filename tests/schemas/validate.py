"""Validates payloads against the contract's JSON Schemas with the
`jsonschema` package (PyPI), independently of the Rust code that generated
the schemas and the payloads.

    python3 tests/schemas/validate.py SCHEMA_DIR PAYLOAD_DIR

PAYLOAD_DIR holds one `{name}.jsonl` per schema `{name}.schema.json`, one
payload per line. Prints one JSON object: per schema, the payloads checked
and the first errors; exits 1 when any payload is invalid."""

import json
import pathlib
import sys

import jsonschema


def main():
    schema_dir = pathlib.Path(sys.argv[1])
    payload_dir = pathlib.Path(sys.argv[2])
    report = {}
    failed = False
    for lines in sorted(payload_dir.glob("*.jsonl")):
        name = lines.name[: -len(".jsonl")]
        schema = json.loads((schema_dir / f"{name}.schema.json").read_text())
        validator_class = jsonschema.validators.validator_for(schema)
        validator_class.check_schema(schema)
        validator = validator_class(schema)
        checked, errors = 0, []
        for n, line in enumerate(lines.read_text().splitlines(), start=1):
            if not line.strip():
                continue
            checked += 1
            for e in validator.iter_errors(json.loads(line)):
                path = "/".join(str(p) for p in e.absolute_path)
                errors.append(f"line {n}, at /{path}: {e.message}")
        failed |= bool(errors)
        report[name] = {"checked": checked, "invalid": len(errors), "errors": errors[:5]}
    if not report:
        failed = True
        print(f"no payloads (*.jsonl) in {payload_dir}", file=sys.stderr)
    print(json.dumps(report, sort_keys=True))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
