#!/usr/bin/env python3
"""server/openapi.json against the OpenAPI 3.1 schema, the server's source and a running server.

1. The document is a valid OpenAPI 3.1 document (the OpenAPI Initiative's JSON Schema,
   tests/support/openapi-3.1-schema.json), every schema in it is a valid JSON Schema 2020-12, and each
   request example validates against its request body's schema.
2. (The route table, server/src/routes.cc, is held to the document by the C++ test
   ServerRoutes.TableIsTheOpenApiDocument, tests/server/server_routes_test.cc: the same operations, ids, query
   parameters and open paths; the router, the Allow header and the query check are derived from it.)
3. Every documented operation answers a running moreau-server as documented: each request (with no query
   parameter, with every documented one, with an unknown one, for an id that does not exist, and without
   the token on a server that requires one; a parameter that only another method of the path reads
   counts as unknown) gets a status the operation lists, with a content type it
   lists for that status, and a JSON body that validates against the schema it gives.
GET /v1/openapi.json serves the file byte for byte.

Usage: check_openapi.py --server BIN --source-dir DIR
Needs python3-jsonschema (Debian 12: 4.10).
"""

import argparse
import json
import os
import sys
import urllib.error
import urllib.request

import jsonschema

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from server_process import ServerProcess  # noqa: E402

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL:", msg)


def load(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def check_document(doc, oas_schema):
    validator = jsonschema.Draft202012Validator(oas_schema)
    for e in validator.iter_errors(doc):
        fail("not a valid OpenAPI 3.1 document at /%s: %s" % ("/".join(map(str, e.absolute_path)), e.message))
    for name, schema in doc["components"]["schemas"].items():
        try:
            jsonschema.Draft202012Validator.check_schema(schema)
        except jsonschema.SchemaError as e:
            fail("components/schemas/%s is not a valid JSON Schema: %s" % (name, e.message))
    ids = [op["operationId"] for _, _, op in operations(doc)]
    for i in set(x for x in ids if ids.count(x) > 1):
        fail("operationId %s is used twice" % i)
    for path, method, op in operations(doc):
        for mt, content in op.get("requestBody", {}).get("content", {}).items():
            if "example" in content:
                errors = list(validator_for(doc, content["schema"]).iter_errors(content["example"]))
                if errors:
                    fail("%s %s: the request example does not match its schema: %s" % (method.upper(), path, errors[0].message))


def operations(doc):
    for path, item in doc["paths"].items():
        for method in ("get", "post", "delete", "put", "patch"):
            if method in item:
                yield path, method, item[method]


def validator_for(doc, schema):
    # The document is the root that "#/components/..." references resolve against.
    resolver = jsonschema.RefResolver.from_schema(doc)
    return jsonschema.Draft202012Validator(schema, resolver=resolver)


def request(base, method, path, body=None, token=None, headers=None):
    data = json.dumps(body).encode() if body is not None else None
    req = urllib.request.Request(base + path, data=data, method=method)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    if token:
        req.add_header("Authorization", "Bearer " + token)
    for k, v in (headers or {}).items():
        req.add_header(k, v)
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, r.headers.get("Content-Type", ""), r.read(), r.headers
    except urllib.error.HTTPError as e:
        return e.code, e.headers.get("Content-Type", ""), e.read(), e.headers


def request_3(*a, **k):
    return request(*a, **k)[:3]


def example_value(doc, param):
    s = param["schema"]
    if "$ref" in s:
        s = doc["components"]["schemas"][s["$ref"].split("/")[-1]]
    for key in ("default", "minimum"):
        if key in s:
            # A query string spells a boolean as JSON does (true/false), not as Python's str() would.
            return json.dumps(s[key]) if isinstance(s[key], bool) else s[key]
    if "enum" in s:
        return s["enum"][0]
    if "example" in param:
        return param["example"]
    return {"number": 1, "integer": 1, "string": "x"}[s["type"]]


def check_answer(doc, what, op, status, ctype, body):
    responses = op["responses"]
    key = str(status)
    if key not in responses:
        fail("%s: answered %d, which the operation does not list (%s): %s" % (what, status, ", ".join(responses), body[:200]))
        return
    resp = responses[key]
    if "$ref" in resp:
        resp = doc["components"]["responses"][resp["$ref"].split("/")[-1]]
    content = resp.get("content", {})
    media = ctype.split(";")[0].strip()
    if content and media not in content:
        fail("%s: %d came as %s; the document lists %s" % (what, status, media or "no content type", ", ".join(content)))
        return
    if media == "application/json" and body:
        try:
            value = json.loads(body)
        except ValueError as e:
            fail("%s: %d: the body is not JSON: %s" % (what, status, e))
            return
        errors = list(validator_for(doc, content[media]["schema"]).iter_errors(value))
        for e in errors[:3]:
            fail("%s: %d: the body does not match the documented schema at /%s: %s" %
                 (what, status, "/".join(map(str, e.absolute_path)), e.message[:300]))


def concrete(path, job_id, study_id, campaign_id=None, robot_id=None):
    if path.endswith("/kinematics"):  # only a URDF job has link poses
        path = path.replace("{id}", robot_id or job_id)
    if path.startswith("/v1/studies/"):
        path = path.replace("{id}", study_id)
    if path.startswith("/v1/campaigns/"):
        path = path.replace("{id}", campaign_id or job_id)
    return path.replace("{id}", job_id).replace("{name}", "manipulator")


def check_live(doc, doc_text, server_bin, scenes):
    with ServerProcess(server_bin, scenes) as srv:
        base = srv.url
        status, ctype, body = request_3(base, "GET", "/v1/openapi.json")
        if status != 200 or body.decode() != doc_text:
            fail("GET /v1/openapi.json is not server/openapi.json byte for byte (status %d)" % status)

        # A finished job and a finished study for the operations on one of them.
        ops = {(p, m): op for p, m, op in operations(doc)}
        job_body = {"scene": "manipulator", "overrides": ["integrator.t_end=0.5"]}
        study_body = {"scene": "manipulator", "overrides": ["integrator.t_end=0.5"],
                      "study": {"h": "1e-2,1e-3", "schemes": ["abl"], "repeats": 1}}
        campaign_body = {"scene": "manipulator-fig6.4", "overrides": ["integrator.t_end=3"],
                         "campaign": {"inputs": [{"path": "/parameters/m2", "distribution": {"type": "uniform", "low": 0.8, "high": 1.2}},
                                                 {"path": "/initial/q/0", "distribution": {"type": "uniform", "low": 2, "high": 4}}],
                                      "sampler": "sobol", "samples": 8, "seed": 1}}
        for name, body_, schema_path in (("job", job_body, "/v1/jobs"), ("study", study_body, "/v1/studies"),
                                         ("campaign", campaign_body, "/v1/campaigns")):
            schema = ops[(schema_path, "post")]["requestBody"]["content"]["application/json"]["schema"]
            for e in list(validator_for(doc, schema).iter_errors(body_))[:1]:
                fail("the test's %s request does not match the documented schema: %s" % (name, e.message))
        status, ctype, body = request_3(base, "POST", "/v1/jobs", job_body)
        check_answer(doc, "POST /v1/jobs", ops[("/v1/jobs", "post")], status, ctype, body)
        job_id = json.loads(body)["id"]
        status, ctype, body = request_3(base, "POST", "/v1/studies", study_body)
        check_answer(doc, "POST /v1/studies", ops[("/v1/studies", "post")], status, ctype, body)
        study_id = json.loads(body)["id"]
        status, ctype, body = request_3(base, "POST", "/v1/campaigns", campaign_body)
        check_answer(doc, "POST /v1/campaigns", ops[("/v1/campaigns", "post")], status, ctype, body)
        campaign_id = json.loads(body)["id"]
        # A URDF robot's job, for the operations only such a job answers (the kinematics).
        status, ctype, body = request_3(base, "POST", "/v1/jobs", {"scene": "iiwa14-joint-limit", "overrides": ["integrator.t_end=0.2"]})
        check_answer(doc, "POST /v1/jobs (a URDF robot)", ops[("/v1/jobs", "post")], status, ctype, body)
        robot_id = json.loads(body)["id"]
        for kind, i in (("jobs", job_id), ("jobs", robot_id), ("studies", study_id), ("campaigns", campaign_id)):
            status, _, body = request_3(base, "GET", "/v1/%s/%s?wait=60" % (kind, i))
            if status != 200 or json.loads(body)["state"] != "done":
                fail("the %s %s did not finish: %s" % (kind, i, body[:300]))

        absent = "0123456789abcdef0123456789abcdef"
        posts = {"/v1/jobs": job_body, "/v1/studies": study_body, "/v1/campaigns": campaign_body}
        # Cancelling comes last: it does not change a finished job, but order it after the reads anyway.
        for path, method, op in sorted(operations(doc), key=lambda x: x[1] == "delete"):
            M = method.upper()
            url = concrete(path, job_id, study_id, campaign_id, robot_id)
            body_ = posts.get(path) if M == "POST" else None
            cases = [("", url)]
            query = [p for p in op.get("parameters", []) if p["in"] == "query"]
            if query:
                # A cursor must name a listed job or study: the finished one of that collection.
                cursor = (study_id if path.startswith("/v1/studies") else campaign_id if path.startswith("/v1/campaigns")
                          else job_id)
                cases.append(("every query parameter", url + "?" + "&".join(
                    "%s=%s" % (p["name"], cursor if p["name"] == "before" else example_value(doc, p)) for p in query)))
            cases.append(("an unknown query parameter", url + "?no_such_parameter=1"))
            # A parameter another method of the same path reads is unknown to this one.
            others = {q["name"] for m, o in doc["paths"][path].items() if m != method
                      for q in o.get("parameters", []) if q["in"] == "query"} - {q["name"] for q in query}
            for name in sorted(others):
                cases.append(("an unknown query parameter", url + "?%s=1" % name))
            if "{id}" in path:
                cases.append(("an absent id", concrete(path, absent, absent)))
            if "{name}" in path:
                cases.append(("an absent scene", path.replace("{name}", "no-such-scene")))
            for why, u in cases:
                status, ctype, body, headers = request(base, M, u, body_)
                what = "%s %s%s" % (M, u, " (" + why + ")" if why else "")
                check_answer(doc, what, op, status, ctype, body)
                if why == "" and status >= 400 and not (M == "DELETE" and status == 409):
                    fail("%s: answered %d on a valid request: %s" % (what, status, body[:200]))
                if why == "every query parameter" and status >= 400:
                    fail("%s: a documented query parameter was refused: %s" % (what, body[:300]))
                if why == "an unknown query parameter" and status != 400:
                    fail("%s: answered %d, not 400" % (what, status))
                if why.startswith("an absent") and status != 404:
                    fail("%s: answered %d, not 404" % (what, status))
                # Where an ETag is documented, the same request with it is 304 (and that is documented).
                etag = headers.get("ETag") if status == 200 else None
                if why == "" and "ETag" in op["responses"].get("200", {}).get("headers", {}):
                    if not etag:
                        fail("%s: no ETag, which the document promises" % what)
                    else:
                        s304, c304, b304 = request(base, M, u, body_, headers={"If-None-Match": etag})[:3]
                        check_answer(doc, what + " (If-None-Match)", op, s304, c304, b304)
                        if s304 != 304:
                            fail("%s: If-None-Match with its own ETag answered %d, not 304" % (what, s304))

    token = "openapi-check-token"
    with ServerProcess(server_bin, scenes, ["--token", token]) as srv:
        for path, method, op in operations(doc):
            M = method.upper()
            u = concrete(path, "0123456789abcdef0123456789abcdef", "0123456789abcdef0123456789abcdef")
            status, ctype, body = request_3(srv.url, M, u, posts.get(path) if M == "POST" else None)
            check_answer(doc, "%s %s without the token" % (M, u), op, status, ctype, body)
            needs_token = op.get("security", doc.get("security")) != []
            if needs_token and status != 401:
                fail("%s %s without the token: answered %d, not 401" % (M, u, status))
            if not needs_token and status == 401:
                fail("%s %s is documented as open but answered 401" % (M, u))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--server", required=True)
    ap.add_argument("--source-dir", required=True)
    args = ap.parse_args()
    src = args.source_dir
    doc_text = load(os.path.join(src, "server", "openapi.json"))
    doc = json.loads(doc_text)
    oas_schema = json.loads(load(os.path.join(src, "tests", "support", "openapi-3.1-schema.json")))
    check_document(doc, oas_schema)
    check_live(doc, doc_text, args.server, os.path.join(src, "scenes"))
    n = sum(1 for _ in operations(doc))
    if failures:
        print("%d failure(s) over %d documented operations" % (len(failures), n))
        return 1
    print("server/openapi.json: valid OpenAPI 3.1; %d operations, each answering as documented" % n)
    return 0


if __name__ == "__main__":
    sys.exit(main())
