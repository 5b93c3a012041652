"""What the CLI runs: jobs on one runner (streamed CSV, report with a status, plots)."""
