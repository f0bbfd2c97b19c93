// A ref that always holds the latest committed value: for OpenLayers event handlers and async callbacks that
// are set up once but must call the current prop (updated after each commit, never during render).
import { useLayoutEffect, useRef, type RefObject } from "react";

export function useLatest<T>(value: T): RefObject<T> {
  const ref = useRef(value);
  useLayoutEffect(() => {
    ref.current = value;
  });
  return ref;
}
