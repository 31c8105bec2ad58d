"""The text report of one graded file: its score, then each check's points and reason."""


def format_report(result):
    lines = [f"{result['assignment']}: {result['file']}: {result['score']}/{result['max']}"]
    width = max(len(r["name"]) for r in result["checks"])
    for r in result["checks"]:
        earned = " --" if r.get("skipped") else f"{r['earned']:3d}"   # skipped: neither earned nor lost
        line = f"  {earned}/{r['points']:<3d} {r['name']:<{width}}  {r['what']}"
        if r["reason"]:
            line += f"\n            -> {r['reason']}"
        if r.get("hint"):
            line += f"\n            hint: {r['hint']}"
        lines.append(line)
    if result.get("note"):
        lines.append(f"  note: {result['note']}")
    if result.get("error"):
        lines.append(f"  the grader failed on this file: {result['error']} (the checks it did not grade earn 0)")
    lines.append(f"  graded in {result['seconds']:.1f} s")
    return "\n".join(lines)
