"""The report: report.json and points.csv, report.html, figures, the redundancy map, the faces' picture."""
