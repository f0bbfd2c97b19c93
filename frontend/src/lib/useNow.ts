// The wall clock (ms since the epoch), re-rendering its component every ``periodMs``: for ages that must count
// up between the messages that re-render anyway.
import { useEffect, useState } from "react";

export function useNow(periodMs: number): number {
  const [now, setNow] = useState(() => Date.now());
  useEffect(() => {
    const timer = setInterval(() => setNow(Date.now()), periodMs);
    return () => clearInterval(timer);
  }, [periodMs]);
  return now;
}
